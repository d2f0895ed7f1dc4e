"""Both methods on gmsh meshes against the rectangle's grid (issue 17).

Usage::

    python -m fem_runout.bench meshes [--only thacker hemisphere avakot] [--methods tg2 mpm]
                                      [--out docs/meshes.md]
    mpiexec -n 2 python -m fem_runout.bench meshes ...     # the same numbers on 2 ranks

- Thacker's planar bowl after one period on gmsh meshes of the disc r < 1.95 m around the
  bowl (``domain.outline``, cell size 4/n; the wet disc stays inside r <= 1.5 m) and on the
  n × n grid of the 4 m square: L1 of h on the disc 0.2 m inside the wet/dry line
  (the measure of docs/benchmarks.md, with the nodes' lumped areas), observed orders.
- The hemisphere collapse (seed §4.1.1) on gmsh meshes of the disc r < 25 m and on the grid:
  mean front radius over 16 rays and its spread (max − min)/mean, from the Q1 depth sampled
  along each ray (threshold 1e-3 m).
- avaKot on the graded corridor mesh (cases/avakot_corridor.yaml) against the grid at 10 m
  and 5 m: run-out, affected area, cells, steps and wall time.

The tables go between the ``<!-- meshes-bench -->`` markers of ``--out``; the raw numbers
next to it as ``meshes_bench.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import platform
from pathlib import Path

import numpy as np

__all__ = ["HELP", "add_arguments", "main"]

HELP = "both methods on gmsh meshes vs the grid: Thacker, hemisphere isotropy, avaKot corridor"
ROOT = Path(__file__).resolve().parents[2]
BEGIN, END = "<!-- meshes-bench -->", "<!-- /meshes-bench -->"
#: Thacker's bowl on gmsh meshes: a disc of radius 1.95 m around the bowl's centre (the wet
#: disc never leaves r <= 1.5 m; a square outline gives gmsh's regular grid, not a test).
BOWL = [[round(2.0 + 1.95 * math.cos(t), 9), round(2.0 + 1.95 * math.sin(t), 9)]
        for t in np.linspace(0.0, 2 * math.pi, 129)[:-1]]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--only", nargs="+", default=["thacker", "hemisphere", "avakot"])
    parser.add_argument("--thacker", type=int, nargs="+", default=[25, 50, 100, 200])
    parser.add_argument("--hemisphere", type=float, nargs="+", default=[0.5, 0.25])
    parser.add_argument("--methods", nargs="+", default=None, help="default: every method")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "meshes.md")


def outline_overrides(points: list[list[float]], size: float) -> list[str]:
    """Case overrides that mesh the polygon ``points`` with gmsh at ``size`` (min ``size/2``)."""
    return ["domain.extent=null", "domain.cells=null", f"domain.outline={points}",
            f"domain.cell_size={size}", f"domain.min_size={size / 2}"]


def thacker_level(n: int, gmsh: bool, comm, method: str) -> dict:
    """One level of Thacker's bowl (one period): error, cells, steps, wall."""
    from fem_runout.api import run
    from fem_runout.config import load_case
    from fem_runout.references import thacker as ref

    over = outline_overrides(BOWL, ref.L / n) if gmsh else []
    case = load_case(ref.case_dict(n), [*over, f"method={method}"])
    r = run(case, write=False, comm=comm)
    err = None
    if r.x is not None:
        wt = ref.omega(case.gravity) * r.t
        rho = np.hypot(r.x - ref.L / 2 - ref.ETA * math.cos(wt),
                       r.y - ref.L / 2 - ref.ETA * math.sin(wt))
        inside = rho <= 0.8 * ref.A
        err = float(np.sum(r.area[inside] * np.abs(r.h - ref.depth(r.x, r.y, r.t))[inside]))
    return {"n": n, "mesh": "gmsh" if gmsh else "grid", "cells": r.cells, "steps": r.steps,
            "wall": r.wall_time, "error": comm.bcast(err, root=0), "method": method}


def hemisphere_level(size: float, gmsh: bool, comm, method: str) -> dict:
    """Run the hemisphere to 1.2 s: mean front radius over 16 rays and its relative spread."""
    from fem_runout.api import run
    from fem_runout.callbacks import KeepSolver
    from fem_runout.config import load_case
    from fem_runout.output.sampling import ray_front_radii

    theta = np.linspace(0.0, 2 * np.pi, 129)[:-1]
    disc_outline = [[float(round(25 + 25 * math.cos(t), 6)), float(round(25 + 25 * math.sin(t),
                                                                           6))] for t in theta]
    n = round(50 / size)
    over = outline_overrides(disc_outline, size) if gmsh else [f"domain.cells=[{n},{n}]"]
    keep = KeepSolver()
    r = run(load_case(ROOT / "cases" / "hemisphere.yaml", [*over, f"method={method}"]),
            write=False, comm=comm, callbacks=[keep])
    radii = ray_front_radii(keep.solver.disc, keep.solver.fields["h"].x.array, (25.0, 25.0),
                            np.linspace(0.0, 2 * np.pi, 17)[:-1], 20.0, 1e-3)
    out = None
    if radii is not None:
        out = {"size": size, "mesh": "gmsh" if gmsh else "grid", "cells": r.cells,
               "method": method,
               "steps": r.steps, "wall": r.wall_time, "mean_radius": float(radii.mean()),
               "spread": float((radii.max() - radii.min()) / radii.mean())}
    return comm.bcast(out, root=0)


def avakot_level(label: str, overrides: list[str], case: Path, comm,
                 method: str) -> dict:
    """One avaKot run: run-out, area, cells, steps, wall."""
    from fem_runout.api import run
    from fem_runout.config import load_case

    r = run(load_case(case, [*overrides, f"method={method}"]), write=False, comm=comm)
    s = r.summary
    return {"label": label, "method": method, "cells": r.cells, "steps": r.steps,
            "wall": r.wall_time, "runout_length": s["runout_length"],
            "affected_area": s["affected_area"],
            "peak_speed_max": s["peak_speed_max"], "deposit_volume": s["deposit_volume"]}


def _orders(rows: list[dict]) -> list[float | None]:
    out: list[float | None] = [None]
    for a, b in zip(rows, rows[1:], strict=False):
        out.append(math.log(a["error"] / b["error"]) / math.log(math.sqrt(b["cells"] /
                                                                           a["cells"])))
    return out


def _table(title: str, header: tuple[str, ...], rows: list[tuple]) -> list[str]:
    """Return a titled markdown table as lines (with a blank line after)."""
    out = [title, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(v) for v in row) + " |" for row in rows]
    return [*out, ""]


def _methods(rows: list[dict]) -> list[str]:
    """Methods of the rows, in the registry's order."""
    from fem_runout.methods import method_names

    have = {_method_of(r) for r in rows}
    return [m for m in method_names() if m in have]


def _method_of(row: dict) -> str:
    """Return the row's method (rows from before DAMPM ran on meshes: the default one)."""
    from fem_runout.methods import default_method

    return row.get("method") or default_method()


def _display(method: str) -> str:
    from fem_runout.methods import get

    return get(method).display


def _tables(res: dict, ranks: int) -> str:
    lines = [f"Measured {datetime.date.today()} on {platform.node()} ({platform.machine()}), "
             f"{ranks} rank(s), `python -m fem_runout.bench meshes`.", ""]
    if "thacker" in res:
        lines += ["Thacker's bowl, one period: L1 of h on the disc 0.2 m inside the wet/dry "
                  "line [m³]", "",
                  "| method | n | mesh | cells | steps | wall [s] | L1 error | order |",
                  "|---|---|---|---|---|---|---|---|"]
        for method in _methods(res["thacker"]):
            for kind in ("grid", "gmsh"):
                rows = [r for r in res["thacker"]
                        if r["mesh"] == kind and _method_of(r) == method]
                for r, o in zip(rows, _orders(rows), strict=True):
                    lines.append(f"| {_display(method)} | {r['n']} | {kind} | {r['cells']} | "
                                 f"{r['steps']} | {r['wall']:.1f} | {r['error']:.3e} | "
                                 f"{'' if o is None else f'{o:.2f}'} |")
        lines.append("")
    if "hemisphere" in res:
        lines += _table("Hemisphere at 1.2 s: front radius over 16 rays (h > 1e-3 m)",
                        ("method", "cell size [m]", "mesh", "cells", "steps", "wall [s]",
                         "mean radius [m]", "spread (max−min)/mean"),
                        [(_display(_method_of(r)), r["size"], r["mesh"], r["cells"],
                          r["steps"], f"{r['wall']:.1f}", f"{r['mean_radius']:.3f}",
                          f"{100 * r['spread']:.1f} %") for r in res["hemisphere"]])
    if "avakot" in res:
        lines += _table("avaKot (defaults)",
                        ("method", "mesh", "cells", "steps", "wall [s]", "run-out [m]",
                         "affected area [ha]", "peak speed [m/s]"),
                        [(_display(_method_of(r)), r["label"], r["cells"], r["steps"],
                          f"{r['wall']:.1f}",
                          f"{r['runout_length']:.0f}", f"{r['affected_area'] / 1e4:.1f}",
                          f"{r['peak_speed_max']:.1f}") for r in res["avakot"]])
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    """Run the ladders and write the tables (collective under mpiexec)."""
    import dolfinx_solver  # noqa: F401  (mpi4py before dolfinx)
    from mpi4py import MPI

    from fem_runout.methods import method_names

    comm = MPI.COMM_WORLD
    methods = args.methods or list(method_names())
    res: dict[str, list[dict]] = {}
    if "thacker" in args.only:
        res["thacker"] = [thacker_level(n, g, comm, m) for m in methods for g in (False, True)
                          for n in args.thacker]
    if "hemisphere" in args.only:
        res["hemisphere"] = [hemisphere_level(s, g, comm, m) for m in methods
                             for s in args.hemisphere for g in (False, True)]
    if "avakot" in args.only:
        grid = ROOT / "cases" / "avakot.yaml"
        corridor = ROOT / "cases" / "avakot_corridor.yaml"
        res["avakot"] = [row for m in methods for row in (
            avakot_level("grid 10 m", [], grid, comm, m),
            avakot_level("grid 5 m", ["domain.cell_size=5"], grid, comm, m),
            avakot_level("gmsh corridor 5–10 m", [], corridor, comm, m))]
    if comm.rank == 0:
        raw = args.out.with_name("meshes_bench.json")
        kept = json.loads(raw.read_text()) if raw.exists() else {}
        for part, rows in res.items():  # the parts and methods not run stay as last measured
            ran = {r["method"] for r in rows}
            rows[:0] = [r for r in kept.get(part, []) if _method_of(r) not in ran]
        res = {**kept, **res}
        text = _tables(res, comm.size)
        print(text)
        raw.write_text(json.dumps(res, indent=1) + "\n")
        doc = args.out.read_text() if args.out.exists() else ""
        block = f"{BEGIN}\n{text}\n{END}"
        if BEGIN in doc:
            doc = doc[: doc.index(BEGIN)] + block + doc[doc.index(END) + len(END):]
        else:
            doc += "\n" + block + "\n"
        args.out.write_text(doc)
    return 0
