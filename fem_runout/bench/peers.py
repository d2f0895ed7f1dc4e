r"""Compare runs of both methods with a peer model's run on the same inputs (rasters only).

Usage::

    python -m fem_runout.bench peers --peer com1dfa=/tmp/com1dfa_avakot/out \\
        --run tg2=results/avakot_tg2 --run mpm=results/avakot_mpm \\
        --doc docs/real_terrain.md --figure docs/figures/avakot_peers.png

Every number is computed the same way from each run's rasters, so the definitions cannot
differ: depth = slope-normal flow thickness (com1DFA's ``pft``; our ``peak_depth_normal``),
affected area = pixel area where the peak thickness reaches 0.1 m and 1 cm, run-out = largest
horizontal distance from the highest release pixel (com1DFA: ``relth > 0``; ours: arrival
time 0) to a pixel reaching the threshold. The peer's run comes from
``peers/com1dfa/run_avakot.py`` (its own virtualenv, never a project dependency).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.bench.markers import splice

__all__ = ["HELP", "add_arguments", "depth_maps_figure", "main", "our_metrics", "peer_metrics",
           "raster_metrics"]

HELP = "compare the methods' runs with a peer model's (com1DFA) from their rasters"
BEGIN, END = "<!-- peers -->", "<!-- /peers -->"
THRESHOLDS = (0.1, 0.01)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--peer", action="append", default=[], metavar="NAME=DIR",
                        help="peer output folder (pft.tif, pfv.tif, relth.tif, dem.tif)")
    parser.add_argument("--run", action="append", default=[], metavar="METHOD=DIR",
                        help="fem_runout output folder (hazard maps and summary.json)")
    parser.add_argument("--dem", type=Path, help="DEM of our runs' rasters (default: the "
                        "case's terrain.dem from case.resolved.yaml)")
    parser.add_argument("--doc", type=Path)
    parser.add_argument("--figure", type=Path)


def _read(path: Path) -> tuple[np.ndarray, Any]:
    import rasterio

    with rasterio.open(path) as src:
        data = src.read(1).astype(float)
        if src.nodata is not None:
            data[data == src.nodata] = np.nan
        return data, src.transform


def raster_metrics(depth: np.ndarray, speed: np.ndarray, release: np.ndarray, z: np.ndarray,
                   transform: Any) -> dict[str, float]:
    """Affected areas, run-out lengths, peaks from rasters on one grid (see the module doc)."""
    rows, cols = np.indices(depth.shape)
    x = transform.c + transform.a * (cols + 0.5)
    y = transform.f + transform.e * (rows + 0.5)
    cell = abs(transform.a * transform.e)
    d = np.nan_to_num(depth, nan=0.0)
    top = np.unravel_index(np.nanargmax(np.where(release, z, -np.inf)), z.shape)
    dist = np.hypot(x - x[top], y - y[top])
    out = {"peak_depth": float(d.max()), "peak_speed": float(np.nanmax(speed))}
    for th in THRESHOLDS:
        hit = d >= th
        out[f"area_{th:g}"] = float(hit.sum() * cell)
        out[f"runout_{th:g}"] = float(dist[hit].max()) if hit.any() else 0.0
    return out


def peer_metrics(folder: Path) -> tuple[dict[str, float], np.ndarray, Any]:
    """Metrics, peak thickness and transform of a com1DFA run (``run_avakot.py``'s folder)."""
    depth, tr = _read(folder / "pft.tif")
    speed, _ = _read(folder / "pfv.tif")
    release, _ = _read(folder / "relth.tif")
    z, _ = _read(folder / "dem.tif")
    summary = json.loads((folder / "summary.json").read_text())
    m = raster_metrics(depth, speed, np.nan_to_num(release) > 0, z, tr)
    m["released_volume"] = float(summary.get("released_volume_m3", np.nan))
    m["wall_time"] = float(summary.get("wall_time_total_s", summary.get("wall_time", np.nan)))
    return m, depth, tr


def our_metrics(folder: Path, dem: Path | None = None) -> tuple[dict[str, float], np.ndarray, Any]:
    """Metrics, peak slope-normal thickness and transform of one of our output folders."""
    import yaml

    depth, tr = _read(folder / "peak_depth_normal.tif")
    speed, _ = _read(folder / "peak_speed.tif")
    arrival, _ = _read(folder / "arrival_time.tif")
    if dem is None:
        resolved = yaml.safe_load((folder / "case.resolved.yaml").read_text())
        from fem_runout.config.geo import expand_data_path

        dem = Path(expand_data_path(resolved["terrain"]["dem"]))
    z, _ = _read(dem)
    summary = json.loads((folder / "summary.json").read_text())
    m = raster_metrics(depth, speed, arrival == 0.0, z, tr)
    m["released_volume"] = float(summary["released_volume"])
    m["wall_time"] = float(summary["wall_time"])
    return m, depth, tr


def _table(rows: dict[str, dict[str, float]]) -> str:
    cols = (("runout_0.01", "run-out, 1 cm [m]", "{:.0f}"),
            ("runout_0.1", "run-out, 0.1 m [m]", "{:.0f}"),
            ("area_0.01", "area ≥ 1 cm [ha]", "{:.1f}"),
            ("area_0.1", "area ≥ 0.1 m [ha]", "{:.1f}"),
            ("peak_depth", "peak thickness [m]", "{:.2f}"),
            ("peak_speed", "peak speed [m/s]", "{:.1f}"),
            ("released_volume", "released [m³]", "{:.0f}"), ("wall_time", "wall [s]", "{:.0f}"))
    head = "| run | " + " | ".join(c[1] for c in cols) + " |"
    lines = [head, "|---" * (len(cols) + 1) + "|"]
    for name, m in rows.items():
        vals = [fmt.format(m[k] / (1e4 if k.startswith("area") else 1.0)) for k, _, fmt in cols]
        lines.append(f"| {name} | " + " | ".join(vals) + " |")
    return "\n".join(lines)


def depth_maps_figure(maps: dict[str, tuple[np.ndarray, Any]], path: Path) -> None:
    """Save the peak-thickness maps (name -> (raster, transform)) side by side to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(maps), figsize=(3.6 * len(maps), 5), sharex=True, sharey=True)
    for ax, (name, (depth, tr)) in zip(np.atleast_1d(axes), maps.items(), strict=True):
        extent = (tr.c, tr.c + tr.a * depth.shape[1], tr.f + tr.e * depth.shape[0], tr.f)
        shown = np.where(np.nan_to_num(depth) >= 0.01, depth, np.nan)
        im = ax.imshow(shown, extent=extent, cmap="viridis", vmin=0, vmax=4)
        ax.contour(np.nan_to_num(depth)[::-1], levels=[0.1], colors="r", linewidths=0.7,
                   extent=extent)
        ax.set_title(name, fontsize=10)
        ax.set_aspect("equal")
    fig.colorbar(im, ax=axes, shrink=0.7,
                 label="slope-normal peak thickness [m] (red line: 0.1 m)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def main(args: argparse.Namespace) -> int:
    """Compute the table (and figure), print it, write it between the doc's markers."""
    rows, maps = {}, {}
    try:
        ours = lambda f: our_metrics(f, args.dem)  # noqa: E731
        for specs, read in ((args.peer, peer_metrics), (args.run, ours)):
            for spec in specs:
                name, sep, folder = spec.rpartition("=")
                if not sep or not name:
                    raise ValueError(f"expected NAME=DIR, got {spec!r}")
                rows[name], *maps[name] = read(Path(folder))
    except (OSError, ValueError, KeyError) as exc:  # rasterio's IO errors are OSErrors
        print(f"error: {exc}", file=sys.stderr)
        return 2
    table = _table(rows)
    print(table)
    if args.doc is not None and not splice(args.doc, BEGIN, END, table):
        print(f"{args.doc} has no {BEGIN} markers: table not written")
    if args.figure is not None:
        depth_maps_figure({k: tuple(v) for k, v in maps.items()}, args.figure)
    return 0
