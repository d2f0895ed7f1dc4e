"""DAMPM verification report: ``python -m fem_runout.bench dampm-report [--out FILE]``.

Runs the seed's tests with the particle method (dam-break fronts on the TG2 grids, lake at rest
with the full rheology, hemisphere symmetry, mass) and writes a markdown report with the exact
solutions, the default method (TG2-PC) on the same grids and the paper's values. Run it under
``mpiexec -n 2``. Method names and the paper's values come from :mod:`fem_runout.methods`.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from fem_runout.bench.tg2_report import (
    hemisphere_section,
    lake_section,
    paper_front_rows,
    run_case,
    write_report,
)
from fem_runout.methods import METHODS, Method, default_method, get

if TYPE_CHECKING:
    from fem_runout.api import RunResult

HELP = "DAMPM verification: dam-break fronts vs TG2 and the paper, lake at rest, hemisphere."
TIMES = (2.75, 5.5, 8.25, 11.0)
FULL = ("material.friction={law: voellmy, phi_deg: 26, xi: 500}",
        "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}")


def particle_method() -> Method:
    """Return the method verified here: the first registered method with particles."""
    return next(m for m in METHODS.values() if m.particles)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the command."""
    parser.add_argument("--out", default="docs/dampm_verification.md", help="markdown file")
    parser.add_argument("--levels", type=int, default=3, help="dam-break refinement levels")


def _fronts(nx: int, ny: int, *extra: str) -> tuple[list[float], RunResult]:
    r = run_case("inclined_dam_break_450", f"domain.cells=[{nx},{ny}]", "output.every=2.75",
                 *extra)
    s = r.series
    fronts = [float(s["front_x"][int(np.argmin(np.abs(s["t"] - t)))]) for t in TIMES]
    return fronts, r


def _row(label: str, fronts: list[float], r: RunResult, particles: int | None) -> str:
    return (f"| {label} | {particles if particles is not None else '–'} | {r.steps} | "
            f"{r.wall_time:.1f} | " + " | ".join(f"{f:.1f}" for f in fronts) + " |")


def dam_break_section(levels: int) -> list[str]:
    """Fronts of DAMPM and TG2-PC on the same grids, with the exact tip and the paper."""
    from fem_runout.references.inclined_dam_break import exact_front

    pm, grid = particle_method(), get(default_method())
    lines = ["## Inclined dam break (seed §4.1)", "",
             "Front = largest x with grid h > 1e-3 m; [0, 450] × [0, 20] m, open ends, walls "
             f"along the flow, frictionless. {pm.display} with 2 particles per cell and "
             "direction (FLIP 0.9) unless stated; `PIC` is the seed's eq. 38 (flip 0); `ppd 3` "
             "puts 3 × 3 particles per cell (the paper's ~7e3 particles); `particles` is the "
             "count at 11 s, after splitting (docs/dampm.md).", "",
             "| run | particles | steps | wall [s] | 2.75 s | 5.5 s | 8.25 s | 11 s |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for k in range(levels):
        nx, ny = 495 * 2**k, 33 * 2**k
        runs = [(pm, "", ()), (grid, "", ())]
        if k == 0:
            runs[1:1] = [(pm, " ppd 3", ("numerics.particles_per_direction=3",)),
                         (pm, " PIC", ("numerics.flip=0",))]
        for method, variant, extra in runs:
            fronts, r = _fronts(nx, ny, f"method={method.name}", *extra)
            lines.append(_row(f"{method.display}{variant} {nx}×{ny} (dx {450 / nx:.2f})", fronts,
                              r, r.particles if method.particles else None))
    lines.append("| exact tip | | | | " + " | ".join(f"{exact_front(t):.1f}" for t in TIMES)
                 + " |")
    return lines + paper_front_rows("paper {} (1.1e4 cells)")


def main(args: argparse.Namespace) -> int:
    """Run every section and write the report on rank 0."""
    setting = ", Voellmy φ = 26°, ξ = 500, Bingham μ = 2000 Pa s, τ_Y = 30 Pa"
    name = particle_method().name
    return write_report(f"{particle_method().display} verification", "dampm-report", [
        lambda: dam_break_section(args.levels),
        lambda: lake_section(name, *FULL, setting=setting),
        lambda: hemisphere_section(name)], args.out)
