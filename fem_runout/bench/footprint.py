"""Cost against the DEM's size: the same release on its DEM and on one 4× larger (issue 16).

Usage::

    python -m fem_runout.bench footprint [--case cases/avakot.yaml] [--methods tg2 mpm]
                                         [--ranks 1] [--pad 2] [--max-time 600]
                                         [--out docs/performance.md]

The DEM of the case is padded around its rectangle (mirrored terrain, ``--pad`` times the
width and height: 4× the area for 2) and written next to the results as an ESRI ASCII grid;
the case runs on both (``--set terrain.dem=...``), alternately, with the same command line as
users (``python -m fem_runout``). The table gives the wall time of each, their ratio and the
run-out, affected area and peak depth of both (they must agree: the flow never reaches the
padding). The table goes between the ``<!-- footprint -->`` markers of the doc.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np

from fem_runout.bench.markers import between, splice
from fem_runout.methods import method_names

__all__ = ["HELP", "add_arguments", "main", "pad_ascii_grid"]

HELP = "wall time of a case on its DEM and on a 4x larger padded DEM (active-set check)"
ROOT = Path(__file__).resolve().parents[2]
BEGIN, END = "<!-- footprint -->", "<!-- /footprint -->"
KEYS = ("runout_length", "affected_area", "peak_depth_max", "steps", "t_end")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--case", type=Path, default=ROOT / "cases" / "avakot.yaml")
    parser.add_argument("--methods", nargs="+", default=method_names(), choices=method_names())
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--pad", type=float, default=2.0,
                        help="linear size factor of the padded DEM (2: 4x the area)")
    parser.add_argument("--max-time", type=float, default=None,
                        help="override time.max of the case [s]")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "performance.md")
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "footprint")


def pad_ascii_grid(src: Path, dst: Path, factor: float) -> tuple[int, int]:
    """Write ``src`` (ESRI ASCII grid) padded to ``factor`` × its size by mirroring.

    Returns:
        The (ncols, nrows) of the padded grid.
    """
    lines = src.read_text().splitlines()
    head = {}
    for line in lines[:6]:
        key, value = line.split()[:2]
        head[key.lower()] = value
    data = np.loadtxt(lines[6:], ndmin=2)
    rows, cols = data.shape
    px, py = int(round(cols * (factor - 1) / 2)), int(round(rows * (factor - 1) / 2))
    padded = np.pad(data, ((py, py), (px, px)), mode="symmetric")
    size = float(head["cellsize"])
    nodata = head.get("nodata_value", "-9999")
    out = [f"ncols {padded.shape[1]}", f"nrows {padded.shape[0]}",
           f"xllcorner {float(head['xllcorner']) - px * size!r}",
           f"yllcorner {float(head['yllcorner']) - py * size!r}",
           f"cellsize {head['cellsize']}", f"NODATA_value {nodata}"]
    dst.parent.mkdir(parents=True, exist_ok=True)
    with dst.open("w") as fh:
        fh.write("\n".join(out) + "\n")
        np.savetxt(fh, padded, fmt="%.6f")
    return padded.shape[1], padded.shape[0]


def _grid_size(path: Path) -> str:
    """``ncols×nrows`` of an ESRI ASCII grid."""
    head = dict(line.split()[:2] for line in path.read_text().splitlines()[:2])
    return f"{head['ncols']}×{head['nrows']}"


def _dem_of(case: Path) -> Path:
    """Return the DEM path of a case (``${FEM_RUNOUT_DATA}`` expanded as the loader does)."""
    from fem_runout.config import load_case
    from fem_runout.terrain.paths import expand_data_path

    return Path(expand_data_path(str(load_case(case).terrain.dem)))


def _run(case: Path, method: str, ranks: int, out: Path, sets: list[str]) -> dict:
    cmd = [sys.executable, "-m", "fem_runout", str(case), "--method", method, "--out",
           str(out), "--overwrite", "--quiet", "--set", "output.pictures=false"]
    for item in sets:
        cmd += ["--set", item]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks), *cmd]
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    subprocess.run(cmd, check=True, cwd=ROOT, env=env)
    return json.loads((out / "summary.json").read_text())


def _table(rows: list[dict]) -> str:
    head = ("| method | ranks | DEM | DEM cells | wall [s] | ratio | steps | run-out [m] | "
            "area [m²] | peak depth [m] |")
    lines = [head, "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['ranks']} | {r['dem']} | {r['nodes']} | "
                     f"{r['wall_time']:.1f} | {r['ratio']:.2f} | {r['steps']} | "
                     f"{r['runout_length']:.1f} | {r['affected_area']:.0f} | "
                     f"{r['peak_depth_max']:.3f} |")
    return "\n".join(lines)


def _kept_rows(text: str, ran: set[str]) -> list[str]:
    """Return the doc's table rows of the methods not run now (kept as last measured)."""
    block = between(text, BEGIN, END) or ""
    return [line for line in block.splitlines() if line.startswith("| ")
            and not line.startswith("| method") and line.split("|")[1].strip() not in ran]


def main(args: argparse.Namespace) -> int:
    """Run the case on its DEM and the padded one, for each method; update the doc."""
    dem = _dem_of(args.case)
    padded = args.work / f"{dem.stem}_pad{args.pad:g}.asc"
    cols, rows_ = pad_ascii_grid(dem, padded, args.pad)
    extra = [] if args.max_time is None else [f"time.max={args.max_time}"]
    rows = []
    for method in args.methods:
        runs = {}
        for name, sets in (("original", extra), ("padded", [f"terrain.dem={padded}", *extra])):
            out = args.work / f"{method}_{name}"
            runs[name] = _run(args.case, method, args.ranks, out, sets)
        base = runs["original"]["wall_time"]
        for name, s in runs.items():
            nodes = f"{cols}×{rows_}" if name == "padded" else _grid_size(dem)
            rows.append({"method": method, "ranks": args.ranks, "dem": name, "nodes": nodes,
                         "ratio": s["wall_time"] / base,
                         **{k: s[k] for k in ("wall_time", *KEYS)}})
    text = args.out.read_text()
    kept = _kept_rows(text, set(args.methods))
    table = _table(rows) + "".join(f"\n{line}" for line in kept)
    stamp = (f"{datetime.date.today()}, {platform.processor() or platform.machine()}, "
             f"{os.cpu_count()} cores; `python -m fem_runout.bench footprint "
             f"--ranks {args.ranks} --methods {' '.join(args.methods)}`"
             + ("; the other methods' rows as last measured" if kept else ""))
    splice(args.out, BEGIN, END, f"{table}\n\n{stamp}")
    print(table)
    return 0
