"""TG2-PC verification report: ``python -m fem_runout.bench tg2-report [--out FILE]``.

Runs the seed's tests and Ritter's dam break on refinement ladders and writes a markdown report
with our numbers next to the exact solutions and the paper's. Run it under ``mpiexec -n 2``
for speed; the numbers do not depend on the rank count.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fem_runout.methods import METHODS, default_method, get

if TYPE_CHECKING:
    from fem_runout.api import RunResult

HELP = "TG2-PC verification: dam-break fronts, Ritter, lake at rest, hemisphere."
CASES = Path(__file__).resolve().parents[2] / "cases"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the command."""
    parser.add_argument("--out", default="docs/tg2_verification.md", help="markdown file")
    parser.add_argument("--levels", type=int, default=3, help="dam-break refinement levels")


def run_case(name: str, *overrides: str) -> RunResult:
    """Run the shipped case ``cases/<name>.yaml`` with overrides on every rank, no output.

    Returns:
        The :class:`~fem_runout.api.RunResult` (arrays on rank 0).
    """
    from mpi4py import MPI

    from fem_runout.api import run
    from fem_runout.config import load_case

    case = load_case(CASES / f"{name}.yaml", overrides=list(overrides))
    return run(case, write=False, comm=MPI.COMM_WORLD)


def _fronts(nx: int, ny: int) -> tuple[dict[float, float], float, int]:
    """Front positions (h > 1e-3) at the output times on the [0, 450] m slope."""
    r = run_case("inclined_dam_break_450", f"domain.cells=[{nx},{ny}]", "output.every=2.75")
    s = r.series
    fronts = {}
    if r.x is not None:
        for t in (2.75, 5.5, 8.25, 11.0):
            i = int(np.argmin(np.abs(s["t"] - t)))
            fronts[t] = float(s["front_x"][i])
    return fronts, r.wall_time, r.steps


def dam_break_section(levels: int) -> list[str]:
    """Front table of seed §4.1 with the exact tip and the paper's values."""
    from fem_runout.references.inclined_dam_break import exact_front

    lines = ["## Inclined dam break (seed §4.1)", "",
             "Front = largest x with h > 1e-3 m, domain [0, 450] × [0, 20] m (same solution as on "
             "[0, 300] until the front reaches 300 m), open boundaries, frictionless, cfl 0.9.",
             "", "| cells | dx [m] | steps | wall [s] | 2.75 s | 5.5 s | 8.25 s | 11 s |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for k in range(levels):
        nx, ny = 495 * 2**k, 33 * 2**k
        fronts, wall, steps = _fronts(nx, ny)
        cells = [f"{fronts.get(t, float('nan')):.1f}" for t in (2.75, 5.5, 8.25, 11.0)]
        lines.append(f"| {nx}×{ny} | {450 / nx:.3f} | {steps} | {wall:.1f} | " + " | ".join(cells)
                     + " |")
    exact = [f"{exact_front(t):.1f}" for t in (2.75, 5.5, 8.25, 11.0)]
    lines.append("| exact tip | | | | " + " | ".join(exact) + " |")
    lines += paper_front_rows("paper {}")
    return lines


def paper_front_rows(label: str) -> list[str]:
    """Return the seed's fronts at 5.5 and 11 s, a row per registered method that has them.

    Args:
        label: Row label, ``{}`` replaced by the method's display name.
    """
    return [f"| {label.format(m.display)} | | | | | {m.paper['front'][5.5]} | | "
            f"{m.paper['front'][11.0]} |" for m in METHODS.values() if "front" in m.paper]


def ritter_section() -> list[str]:
    """L1 error of h at t = 4 s and observed orders."""
    from fem_runout.references.norms import l1, nodal_weights
    from fem_runout.references.ritter import ritter_depth

    lines = ["## Ritter dry-bed dam break", "",
             "h0 = 1 m behind x0 = 50 m, flat, frictionless, t = 4 s; L1 = ∫|h − h_exact| per "
             "metre of width [m²].", "", "| cells | dx [m] | steps | L1 | order |",
             "|---:|---:|---:|---:|---:|"]
    prev = None
    for nx in (100, 200, 400, 800):
        r = run_case("ritter", f"domain.cells=[{nx},2]", "output.every=4.0")
        if r.x is None:
            continue
        err = l1(r.h - ritter_depth(r.x, 4.0, 1.0, 50.0, 9.81), nodal_weights(r.x, r.y)) / 2.0
        order = "" if prev is None else f"{np.log2(prev / err):.2f}"
        lines.append(f"| {nx}×2 | {100 / nx:.3f} | {r.steps} | {err:.4f} | {order} |")
        prev = err
    return lines


def lake_section(method: str | None = None, *overrides: str, setting: str = "") -> list[str]:
    """Seed Table 2 layout: our numbers beside the paper's (the registry's) for ``method``.

    Args:
        method: A registered method (default: the default method).
        overrides: More case overrides.
        setting: Text after the run description.
    """
    from fem_runout.references.norms import l1, linf, nodal_weights

    method = method or default_method()
    r = run_case("lake_at_rest", f"method={method}", *overrides)
    lines = ["## Lake at rest (seed §4.2, Table 2 layout)", ""]
    if r.x is None:
        return lines
    w = nodal_weights(r.x, r.y)
    eta = np.where(r.h > 1e-6, r.h + r.z - 10.0, 0.0)
    paper, name = get(method).paper["lake"], get(method).display
    lines += [f"50×50 cells, walls, T = 1 s ({r.steps} steps){setting}.", "",
              f"| variable | ours L1 | ours L∞ | paper {name} L1 | paper {name} L∞ |",
              "|---|---:|---:|---:|---:|"]
    for key, v in (("h", eta), ("hu", r.hu), ("hv", r.hv)):
        label = "h + Z − 10" if key == "h" else key
        lines.append(f"| {label} | {l1(v, w):.2e} | {linf(v):.2e} | {paper[key][0]} | "
                     f"{paper[key][1]} |")
    return lines


def hemisphere_section(method: str | None = None) -> list[str]:
    """Front radius along x, y and the diagonal at 1.2 s (default: the default method)."""
    from fem_runout.references.norms import front_radius

    method = method or default_method()
    lines = ["## Hemisphere collapse (seed §4.1.1)", "",
             "Radius 5 m at (25, 25), open boundaries, t = 1.2 s; front = h > 1e-3 m; the paper "
             "reports a diameter of about 13 m.", "",
             "| cells | dx [m] | particles | r_x | r_y | r_diag | max − min | mass error |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for n in (100, 200):
        r = run_case("hemisphere", f"method={method}", f"domain.cells=[{n},{n}]")
        if r.x is None:
            continue
        rad = [front_radius(r.x, r.y, r.h, (25.0, 25.0), 1e-3, d)
               for d in ((1, 0), (0, 1), (np.sqrt(0.5), np.sqrt(0.5)))]
        lines.append(f"| {n}×{n} | {50 / n:.3f} | {r.particles or '–'} | {rad[0]:.2f} | "
                     f"{rad[1]:.2f} | {rad[2]:.2f} | {max(rad) - min(rad):.2f} | "
                     f"{abs(r.series['mass_error']).max():.1e} |")
    return lines


def write_report(title: str, command: str, sections: list[Callable[[], list[str]]],
                 out: str) -> int:
    """Run report sections (collective) and write them under a header on rank 0.

    Args:
        title: Markdown title.
        command: The ``fem_runout.bench`` command that generates the report.
        sections: Functions returning the markdown lines of one section each.
        out: Output file.
    """
    import dolfinx
    from mpi4py import MPI

    start = time.perf_counter()
    lines = [f"# {title}", "",
             f"Generated by `python -m fem_runout.bench {command}` on {platform.machine()} "
             f"({platform.processor() or 'cpu'}), {MPI.COMM_WORLD.size} rank(s), "
             f"{datetime.date.today()}, DOLFINx {dolfinx.__version__}.", ""]
    for section in sections:
        lines += section() + [""]
    lines.append(f"Total time {time.perf_counter() - start:.0f} s.")
    if MPI.COMM_WORLD.rank == 0:
        Path(out).write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
    return 0


def main(args: argparse.Namespace) -> int:
    """Run every section and write the report on rank 0."""
    return write_report(f"{get(default_method()).display} verification", "tg2-report", [
        lambda: dam_break_section(args.levels), ritter_section,
        lambda: lake_section(setting=", friction and rheology off"), hemisphere_section],
        args.out)
