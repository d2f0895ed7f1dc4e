"""DAMPM verification report: ``python -m fem_runout.bench dampm-report [--out FILE]``.

Runs the seed's tests with ``method: mpm`` (dam-break fronts on the TG2 grids, lake at rest
with the full rheology, hemisphere symmetry, mass) and writes a markdown report with the exact
solutions, TG2-PC on the same grids and the paper's values. Run it under ``mpiexec -n 2``.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import time
from pathlib import Path

import numpy as np

from fem_runout.bench.tg2_report import _run

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
             "3 × 3 particles per cell (the paper's ~7e3 particles).", "",
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


def lake_section() -> list[str]:
    """Seed Table 2 layout: our DAMPM next to the paper's DAMPM."""
    from fem_runout.references.norms import l1, linf, nodal_weights

    r = _run("lake_at_rest", "method=mpm", *FULL)
    lines = ["## Lake at rest (seed §4.2, Table 2 layout)", ""]
    if r.x is None:
        return lines
    w = nodal_weights(r.x, r.y)
    eta = np.where(r.h > 1e-6, r.h + r.z - 10.0, 0.0)
    paper = {"h": ("1.26e-12", "1.26e-14"), "hu": ("1.08e-13", "3.57e-14"),
             "hv": ("1.22e-13", "3.25e-14")}
    lines += [f"50×50 cells, walls, T = 1 s ({r.steps} steps), Voellmy φ = 26°, ξ = 500, "
              f"Bingham μ = 2000 Pa s, τ_Y = 30 Pa; {r.particles} particles.", "",
              "| variable | ours L1 | ours L∞ | paper DAMPM L1 | paper DAMPM L∞ |",
              "|---|---:|---:|---:|---:|"]
    for name, v in (("h + Z − 10", eta), ("hu", r.hu), ("hv", r.hv)):
        key = name.split()[0]
        lines.append(f"| {name} | {l1(v, w):.2e} | {linf(v):.2e} | {paper[key][0]} | "
                     f"{paper[key][1]} |")
    return lines


def hemisphere_section() -> list[str]:
    """Front radius along x, y and the diagonal at 1.2 s."""
    from fem_runout.references.norms import front_radius

    lines = ["## Hemisphere collapse (seed §4.1.1)", "",
             "Radius 5 m at (25, 25), open boundaries, t = 1.2 s; front = grid h > 1e-3 m.", "",
             "| run | particles | r_x | r_y | r_diag | max − min | mass error |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for n in (100, 200):
        r = _run("hemisphere", "method=mpm", f"domain.cells=[{n},{n}]")
        if r.x is None:
            continue
        rad = [front_radius(r.x, r.y, r.h, (25.0, 25.0), 1e-3, d)
               for d in ((1, 0), (0, 1), (np.sqrt(0.5), np.sqrt(0.5)))]
        lines.append(f"| DAMPM {n}×{n} | {r.particles} | {rad[0]:.2f} | {rad[1]:.2f} | "
                     f"{rad[2]:.2f} | {max(rad) - min(rad):.2f} | "
                     f"{abs(r.series['mass_error']).max():.1e} |")
    return lines


def main(args: argparse.Namespace) -> int:
    """Run every section and write the report on rank 0."""
    import dolfinx
    from mpi4py import MPI

    start = time.perf_counter()
    lines = ["# DAMPM verification", "",
             f"Generated by `python -m fem_runout.bench dampm-report` on {platform.machine()} "
             f"({platform.processor() or 'cpu'}), {MPI.COMM_WORLD.size} rank(s), "
             f"{datetime.date.today()}, DOLFINx {dolfinx.__version__}.", ""]
    for section in (dam_break_section(args.levels), lake_section(), hemisphere_section()):
        lines += section + [""]
    lines.append(f"Total time {time.perf_counter() - start:.0f} s.")
    if MPI.COMM_WORLD.rank == 0:
        Path(args.out).write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
    return 0
