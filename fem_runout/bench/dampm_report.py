"""DAMPM verification report: ``python -m fem_runout.bench dampm-report [--out FILE]``.

Runs the seed's tests with ``method: mpm`` (dam-break fronts on the TG2 grids, lake at rest
with the full rheology, hemisphere symmetry, mass) and writes a markdown report with the exact
solutions, TG2-PC on the same grids and the paper's values. Run it under ``mpiexec -n 2``.
"""

from __future__ import annotations

import argparse

import numpy as np

from fem_runout.bench.tg2_report import _run, hemisphere_section, lake_section, write_report

HELP = "DAMPM verification: dam-break fronts vs TG2 and the paper, lake at rest, hemisphere."
TIMES = (2.75, 5.5, 8.25, 11.0)
FULL = ("material.friction={law: voellmy, phi_deg: 26, xi: 500}",
        "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the command."""
    parser.add_argument("--out", default="docs/dampm_verification.md", help="markdown file")
    parser.add_argument("--levels", type=int, default=3, help="dam-break refinement levels")


def _fronts(nx: int, ny: int, *extra: str) -> tuple[list[float], object]:
    r = _run("inclined_dam_break_450", f"domain.cells=[{nx},{ny}]", "output.every=2.75", *extra)
    s = r.series
    fronts = [float(s["front_x"][int(np.argmin(np.abs(s["t"] - t)))]) for t in TIMES]
    return fronts, r


def _row(label: str, fronts: list[float], r, particles: int | None) -> str:
    return (f"| {label} | {particles if particles is not None else '–'} | {r.steps} | "
            f"{r.wall_time:.1f} | " + " | ".join(f"{f:.1f}" for f in fronts) + " |")


def dam_break_section(levels: int) -> list[str]:
    """Fronts of DAMPM and TG2-PC on the same grids, with the exact tip and the paper."""
    from fem_runout.references.inclined_dam_break import PAPER_FRONT, exact_front

    lines = ["## Inclined dam break (seed §4.1)", "",
             "Front = largest x with grid h > 1e-3 m; [0, 450] × [0, 20] m, open ends, walls "
             "along the flow, frictionless. DAMPM with 2 particles per cell and direction "
             "(FLIP 0.9) unless stated; `PIC` is the seed's eq. 38 (flip 0); `ppd 3` puts "
             "3 × 3 particles per cell (the paper's ~7e3 particles); `particles` is the count at "
             "11 s, after splitting (docs/dampm.md).", "",
             "| run | particles | steps | wall [s] | 2.75 s | 5.5 s | 8.25 s | 11 s |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for k in range(levels):
        nx, ny = 495 * 2**k, 33 * 2**k
        runs = [("DAMPM", ("method=mpm",)), ("TG2-PC", ("method=tg2",))]
        if k == 0:
            runs[1:1] = [("DAMPM ppd 3", ("method=mpm", "numerics.particles_per_direction=3")),
                         ("DAMPM PIC", ("method=mpm", "numerics.flip=0"))]
        for label, extra in runs:
            fronts, r = _fronts(nx, ny, *extra)
            lines.append(_row(f"{label} {nx}×{ny} (dx {450 / nx:.2f})", fronts, r,
                              r.particles if label.startswith("DAMPM") else None))
    lines.append("| exact tip | | | | " + " | ".join(f"{exact_front(t):.1f}" for t in TIMES)
                 + " |")
    for name in ("tg2", "dampm"):
        lines.append(f"| paper {name.upper()} (1.1e4 cells) | | | | | {PAPER_FRONT[name][5.5]} | "
                     f"| {PAPER_FRONT[name][11.0]} |")
    return lines


def main(args: argparse.Namespace) -> int:
    """Run every section and write the report on rank 0."""
    setting = ", Voellmy φ = 26°, ξ = 500, Bingham μ = 2000 Pa s, τ_Y = 30 Pa"
    return write_report("DAMPM verification", "dampm-report", [
        lambda: dam_break_section(args.levels),
        lambda: lake_section("mpm", *FULL, setting=setting),
        lambda: hemisphere_section("mpm")], args.out)
