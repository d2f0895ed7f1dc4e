"""Ensemble products on the DEM grid.

Exceedance probabilities, mean and percentile maps, the distribution of the run-out numbers and
their sensitivity to each varied parameter.

Inputs are the members' own GeoTIFF peak maps (every member writes them on the same grid) and
``summary.json`` numbers; failed members are listed but left out. A pixel is counted where a
member's map has data; probabilities are ``(members with value >= threshold) / members``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.ensemble.spec import EnsembleSpec
from fem_runout.output.hazard import NODATA, GridTarget, write_rasters

__all__ = ["QUANTITIES", "SUMMARY_COLUMNS", "exceedance", "percentile_maps", "rank_correlation",
           "read_stack", "write_products"]

#: Quantity -> (member raster, factor to the threshold's unit, unit).
QUANTITIES = {"depth": ("peak_depth", 1.0, "m"), "speed": ("peak_speed", 1.0, "m/s"),
              "pressure": ("peak_pressure", 1e-3, "kPa")}
#: summary.json numbers tabulated per member.
SUMMARY_COLUMNS = ("runout_length", "travel_angle_deg", "affected_area", "deposit_volume",
                   "peak_speed_max", "peak_depth_max", "wall_time")


def read_stack(folders: list[Path], name: str) -> tuple[np.ndarray, GridTarget]:
    """``(members, rows, cols)`` stack of one raster (NaN where nodata) and its grid."""
    import rasterio

    layers, target = [], None
    for folder in folders:
        with rasterio.open(folder / f"{name}.tif") as src:
            data = src.read(1).astype(float)
            data[data == src.nodata] = np.nan
            target = target or GridTarget(data.shape, src.transform, src.crs)
        layers.append(data)
    return np.stack(layers), target


def exceedance(stack: np.ndarray, threshold: float) -> np.ndarray:
    """Fraction of members reaching ``threshold`` per pixel (NaN where no member has data)."""
    valid = np.isfinite(stack)
    count = valid.sum(axis=0)
    hits = np.where(valid, stack >= threshold, False).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, hits / np.maximum(count, 1), np.nan)


def percentile_maps(stack: np.ndarray, percentiles: tuple[float, ...]) -> dict[str, np.ndarray]:
    """Mean and percentile maps over the members (a member without data counts as 0)."""
    full = np.nan_to_num(stack, nan=0.0)
    none = ~np.isfinite(stack).any(axis=0)
    maps = {"mean": full.mean(axis=0)}
    for p in percentiles:
        maps[f"p{p:g}"] = np.percentile(full, p, axis=0)
    return {k: np.where(none, np.nan, v) for k, v in maps.items()}


def rank_correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman rank correlation of two samples (ties get average ranks; NaN if constant)."""
    from scipy.stats import spearmanr

    if np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan")
    return float(spearmanr(x, y).statistic)


def _nodata(values: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(values), values, NODATA)


def _maps(spec: EnsembleSpec, folders: list[Path], out: Path
          ) -> tuple[dict[str, np.ndarray], GridTarget]:
    written: dict[str, np.ndarray] = {}
    target = None
    for quantity, (raster, factor, unit) in QUANTITIES.items():
        stack, target = read_stack(folders, raster)
        stack = stack * factor
        for th in getattr(spec.thresholds, quantity):
            written[f"probability_{quantity}_ge_{th:g}{unit.replace('/', '')}"] = \
                exceedance(stack, th)
        if quantity == "depth":
            for name, values in percentile_maps(stack, spec.percentiles).items():
                written[f"peak_depth_{name}"] = values
    write_rasters({k: _nodata(v) for k, v in written.items()}, target, out)
    return written, target


def _table(records: list[dict[str, Any]], keys: list[str], path: Path) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["member", "key", *keys, *SUMMARY_COLUMNS, "error"])
        for r in records:
            s = r.get("summary") or {}
            w.writerow([r["index"], r["key"], *(repr(r["values"][k]) for k in keys),
                        *(s.get(c, "") for c in SUMMARY_COLUMNS), r.get("error") or ""])


def sensitivity(records: list[dict[str, Any]], keys: list[str]) -> dict[str, dict[str, float]]:
    """Spearman correlation of run-out, area and travel angle with each varied key."""
    ok = [r for r in records if not r.get("error")]
    result = {}
    for out_name in ("runout_length", "affected_area", "travel_angle_deg"):
        y = np.array([r["summary"][out_name] for r in ok], dtype=float)
        result[out_name] = {k: rank_correlation(np.array([r["values"][k] for r in ok]), y)
                            for k in keys}
    return result


def write_products(spec: EnsembleSpec, records: list[dict[str, Any]], out: Path
                   ) -> dict[str, Any]:
    """Write every product into ``out``; return the ensemble's summary (also ``ensemble.json``).

    Args:
        spec: The ensemble.
        records: Every member's record (``run_member``), in member order.
        out: The ensemble's folder (members under ``out/members``).
    """
    import json

    from fem_runout.ensemble.pictures import draw_products

    keys = list(spec.vary)
    ok = [r for r in records if not r.get("error")]
    folders = [out / "members" / r["key"] for r in ok]
    maps, target = _maps(spec, folders, out) if ok else ({}, None)
    _table(records, keys, out / "members.csv")
    sens = sensitivity(records, keys) if len(ok) > 2 else {}
    summary = {"members": len(records), "failed": len(records) - len(ok), "varied": keys,
               "plan": spec.sampling.plan, "seed": spec.sampling.seed, "sensitivity": sens,
               "products": sorted(f"{k}.tif" for k in maps)}
    (out / "ensemble.json").write_text(json.dumps(summary, indent=1) + "\n")
    if ok:
        draw_products(maps, target, ok, sens, out)
    return summary
