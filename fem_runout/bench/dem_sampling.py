"""How much a real-terrain result depends on where the mesh samples the DEM.

Usage::

    python -m fem_runout.bench dem-sampling [--methods mpm tg2] [--ranks 2]
                                            [--case cases/avakot.yaml] [--cell-size 5]
                                            [--scales 0 10] [--doc docs/real_terrain.md]

A mesh whose nodes are not the DEM's pixel centres samples the DEM between them (bilinearly);
the comparison that isolates this from everything else is the same grid on the DEM resampled
at its pixel centres shifted by half a pixel diagonally (:func:`half_pixel_shift`, the four
diagonals, written next to the results; the release polygons stay where they are). For each
method and each ``model.curvature_scale`` (0: the Hessian of the nodal bed) the case runs on
the DEM and on the four shifted DEMs with ``python -m fem_runout`` under ``mpiexec -n R``
into ``results/dem_sampling/<method>_<scale>_<dem>`` (a run whose ``summary.json`` is there
is not repeated with ``--keep``). The table (run-out, affected area, peak speed on the DEM,
the range over the shifts and the largest change) is printed and written between the doc's
``<!-- dem-sampling -->`` markers.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.bench.markers import splice
from fem_runout.bench.real_case import ROOT, add_variant_arguments, run_case
from fem_runout.config import load_case
from fem_runout.methods import get
from fem_runout.terrain.dem import read_raster

__all__ = ["HELP", "add_arguments", "half_pixel_shift", "main", "write_shifted"]

HELP = "real-terrain result against half a pixel of DEM sampling (with model.curvature_scale)"
BEGIN, END = "<!-- dem-sampling -->", "<!-- /dem-sampling -->"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    add_variant_arguments(parser)
    parser.add_argument("--cell-size", type=float, default=5.0,
                        help="domain.cell_size [m] (the DEM's pixel: nodes on its centres)")
    parser.add_argument("--scales", type=float, nargs="+", default=[0.0, 10.0],
                        help="model.curvature_scale values [m]; 0 leaves it unset")
    parser.add_argument("--keep", action="store_true",
                        help="reuse the runs whose summary.json exists")


#: The four diagonal half-pixel shifts: name -> (rows, columns) towards which the samples move.
SHIFTS = {"se": (1, 1), "sw": (1, -1), "ne": (-1, 1), "nw": (-1, -1)}


def half_pixel_shift(values: np.ndarray, rows: int = 1, cols: int = 1) -> np.ndarray:
    """Resample a raster bilinearly at its pixel centres moved half a pixel diagonally.

    The value at pixel ``(r, c)`` becomes the mean of ``(r, c), (r, c+cols), (r+rows, c),
    (r+rows, c+cols)`` (the bilinear value at the shared corner; ``rows, cols`` = ±1, row 0
    north: ``(1, 1)`` moves the samples south-east); the edge rows and columns repeat their
    neighbours'. NaN (nodata) wherever one of the four is NaN.
    """
    pad = ((0, 1) if rows > 0 else (1, 0), (0, 1) if cols > 0 else (1, 0))
    p = np.pad(np.asarray(values, dtype=float), pad, mode="edge")
    return 0.25 * (p[:-1, :-1] + p[:-1, 1:] + p[1:, :-1] + p[1:, 1:])


def write_shifted(dem: Path, out: Path, rows: int = 1, cols: int = 1) -> Path:
    """Write :func:`half_pixel_shift` of ``dem`` as a GeoTIFF ``out`` (same grid and CRS)."""
    import rasterio

    raster = read_raster(dem, "terrain.dem")
    out.parent.mkdir(parents=True, exist_ok=True)
    profile = {"driver": "GTiff", "height": raster.shape[0], "width": raster.shape[1],
               "count": 1, "dtype": "float64", "transform": raster.transform,
               "crs": raster.crs, "nodata": np.nan}
    with rasterio.open(out, "w", **profile) as dst:
        dst.write(half_pixel_shift(raster.values, rows, cols), 1)
    return out


def _cells(ref: dict[str, Any], shifted: list[dict[str, Any]], key: str, unit: float,
           fmt: str) -> str:
    x = ref[key] / unit
    ys = [s[key] / unit for s in shifted]
    worst = max((y / x - 1 for y in ys), key=abs)
    return f"{x:{fmt}} | {min(ys):{fmt}}–{max(ys):{fmt}} ({worst:+.1%})"


def _row(method: str, scale: float, ref: dict[str, Any], shifted: list[dict[str, Any]]) -> str:
    label = f"{scale:g} m" if scale > 0 else "none (nodes)"
    return (f"| {get(method).display} | {label} | "
            f"{_cells(ref, shifted, 'runout_length', 1.0, '.1f')} | "
            f"{_cells(ref, shifted, 'affected_area', 1e4, '.2f')} | "
            f"{_cells(ref, shifted, 'peak_speed_max', 1.0, '.1f')} |")


def _summary(args: argparse.Namespace, method: str, out: Path, extra: list[str]) -> dict:
    """Run the case into ``out`` (unless kept) and return its summary."""
    if not (args.keep and (out / "summary.json").is_file()):
        run_case(args.case, method, args.ranks, out, extra)
    return json.loads((out / "summary.json").read_text())


def main(args: argparse.Namespace) -> int:
    """Run every method and scale on the DEM and the shifted DEMs; print and write the table."""
    case = load_case(args.case)
    if case.terrain.dem is None:
        raise SystemExit(f"{args.case} has no terrain.dem")
    root = ROOT / "results" / "dem_sampling"
    dem = case.resolve_input(case.terrain.dem)
    dems = {name: ["--set", f"terrain.dem={write_shifted(dem, root / f'dem_{name}.tif', *d)}"]
            for name, d in SHIFTS.items()}
    lines = ["| method | `model.curvature_scale` | run-out [m], DEM | over the 4 shifts "
             "(largest change) | area [ha], DEM | over the shifts | peak speed [m/s], DEM | "
             "over the shifts |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    for method in args.methods:
        for scale in args.scales:
            extra = ["--set", f"domain.cell_size={args.cell_size:g}"]
            if scale > 0:
                extra += ["--set", f"model.curvature_scale={scale:g}"]
            ref = _summary(args, method, root / f"{method}_{scale:g}_dem", extra)
            shifted = [_summary(args, method, root / f"{method}_{scale:g}_{name}", extra + d)
                       for name, d in dems.items()]
            lines.append(_row(method, scale, ref, shifted))
    table = "\n".join(lines)
    print(table)
    if not splice(args.doc, BEGIN, END, table):
        print(f"{args.doc} has no {BEGIN} markers: table not written")
    return 0
