"""avaKot on the corridor mesh against the 5 m grid, each over a cloud of perturbed runs.

Usage::

    mpiexec -n 2 python -m fem_runout.bench corridor-spread [--members 4] [--methods tg2]
                                                            [--out docs/meshes.md]

A single avaKot run's affected area is not a sharp number: the flow is sensitive to its
data (session 42: changes of the CFL number by 1e-4 to 3e-4, which change every time step
by as much, spread the 5 m grid's TG2-PC area at 600 s over 1.7 % of its mean and the
corridor's over 6.6 %). Comparing one corridor run with one grid run compares two draws.
This bench runs
``--members`` draws of each — the case as it is and with ``time.cfl`` changed by ``−1e-4,
+1e-4, −2e-4, …`` relative — and compares the clouds: mean, smallest and largest run-out
and affected area of each mesh, the ratio of the means, and the range of the ratios over
every pair of draws (corridor draw / grid draw).

The table goes between the ``<!-- corridor-spread -->`` markers of ``--out``.
"""

from __future__ import annotations

import argparse
import datetime
import platform
from pathlib import Path

import numpy as np

from fem_runout.bench.markers import splice

__all__ = ["HELP", "add_arguments", "cfl_offsets", "compare_clouds", "main"]

HELP = "avaKot corridor against the 5 m grid over perturbed draws (CFL changed by 1e-4)"
ROOT = Path(__file__).resolve().parents[2]
BEGIN, END = "<!-- corridor-spread -->", "<!-- /corridor-spread -->"
#: Relative change of the CFL number between draws.
STEP = 1e-4
MESHES = (("grid 5 m", ROOT / "cases" / "avakot.yaml", ["domain.cell_size=5"]),
          ("gmsh corridor 5–10 m", ROOT / "cases" / "avakot_corridor.yaml", []))
KEYS = (("runout_length", "run-out [m]", 1.0, "{:.1f}"),
        ("affected_area", "affected area [ha]", 1e-4, "{:.2f}"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    from fem_runout.methods import default_method

    parser.add_argument("--members", type=int, default=4, help="draws per mesh (default 4)")
    parser.add_argument("--methods", nargs="+", default=[default_method()])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "meshes.md")


def cfl_offsets(members: int) -> list[float]:
    """Relative CFL changes of the draws: ``0, −1, +1, −2, +2, …`` times :data:`STEP`."""
    out = [0.0]
    k = 1
    while len(out) < members:
        out.append(-k * STEP)
        if len(out) < members:
            out.append(k * STEP)
        k += 1
    return out


def compare_clouds(grid: list[float], corridor: list[float]) -> dict[str, float]:
    """Statistics of two clouds of one quantity.

    Args:
        grid: The grid's draws.
        corridor: The corridor's draws.

    Returns:
        ``mean_ratio`` (corridor mean / grid mean − 1), ``low`` and ``high`` (the smallest
        and largest corridor draw / grid draw − 1 over every pair), and each cloud's
        relative half range ``grid_spread``, ``corridor_spread`` ((max − min) / (2 mean)).
    """
    g, c = np.asarray(grid, float), np.asarray(corridor, float)
    pairs = c[:, None] / g[None, :] - 1.0
    return {"mean_ratio": float(c.mean() / g.mean() - 1.0), "low": float(pairs.min()),
            "high": float(pairs.max()),
            "grid_spread": float(np.ptp(g) / (2 * g.mean())),
            "corridor_spread": float(np.ptp(c) / (2 * c.mean()))}


def _draws(method: str, members: int, comm) -> dict[str, list[dict]]:
    """Run every draw of both meshes (collective)."""
    from fem_runout.bench.meshes import avakot_level
    from fem_runout.config import load_case

    out: dict[str, list[dict]] = {}
    for label, case, sets in MESHES:
        cfl = load_case(case, sets).time.cfl
        out[label] = [avakot_level(label, [*sets, f"time.cfl={cfl * (1 + d)!r}"], case, comm,
                                   method) for d in cfl_offsets(members)]
    return out


def table(method: str, draws: dict[str, list[dict]]) -> list[str]:
    """Markdown lines: every draw, then the clouds' comparison."""
    from fem_runout.methods import get

    offsets = cfl_offsets(len(next(iter(draws.values()))))
    lines = [f"{get(method).display}: every draw", "",
             "| mesh | CFL change | cells | steps | wall [s] | run-out [m] | affected area [ha] |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for label, rows in draws.items():
        lines += [f"| {label} | {d:+.0e} | {r['cells']} | {r['steps']} | {r['wall']:.1f} | "
                  f"{r['runout_length']:.1f} | {r['affected_area'] / 1e4:.2f} |"
                  for d, r in zip(offsets, rows, strict=True)]
    (glabel, grows), (clabel, crows) = draws.items()
    lines += ["", f"{get(method).display}: {clabel} against {glabel}", "",
              "| quantity | grid mean (min–max) | corridor mean (min–max) | ratio of the means "
              "| range over the pairs of draws |", "|---|---|---|---:|---|"]
    for key, name, scale, fmt in KEYS:
        g = [r[key] * scale for r in grows]
        c = [r[key] * scale for r in crows]
        s = compare_clouds(g, c)
        lines.append(f"| {name} | {fmt.format(np.mean(g))} ({fmt.format(min(g))}–"
                     f"{fmt.format(max(g))}) | {fmt.format(np.mean(c))} ({fmt.format(min(c))}–"
                     f"{fmt.format(max(c))}) | {s['mean_ratio']:+.1%} | "
                     f"{s['low']:+.1%} … {s['high']:+.1%} |")
    return [*lines, ""]


def main(args: argparse.Namespace) -> int:
    """Run the draws of every method and write the tables (collective under mpiexec)."""
    import dolfinx_solver  # noqa: F401  (mpi4py before dolfinx)
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    lines = [f"Measured {datetime.date.today()} on {platform.node()} ({platform.machine()}), "
             f"{comm.size} rank(s), `python -m fem_runout.bench corridor-spread "
             f"--members {args.members}`.", ""]
    for method in args.methods:
        lines += table(method, _draws(method, args.members, comm))
    if comm.rank == 0:
        text = "\n".join(lines)
        print(text)
        if not splice(args.out, BEGIN, END, text):
            print(f"{args.out}: no {BEGIN} markers, the table was only printed")
    return 0
