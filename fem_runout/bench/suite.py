"""Benchmark suite: ``python -m fem_runout.bench suite [--out docs/benchmarks.md]``.

For every registered method (:mod:`fem_runout.methods`) and every benchmark of
:data:`BENCHMARKS`, the driver (which does not import dolfinx) starts one worker per rank count
(``mpiexec -n R`` for R > 1, one thread per rank) that runs the whole refinement ladder and
prints one ``SUITE_RESULT {json}`` line per level. Hard cases run once per method on 1 rank.
The driver writes the markdown report and one error-against-wall-time figure per benchmark
(:mod:`fem_runout.bench.suite_report`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from fem_runout.bench import ladders
from fem_runout.bench.ladders import Benchmark
from fem_runout.methods import method_names

HELP = "all benchmarks, both methods, 1 and 2 ranks: docs/benchmarks.md + figures"
TAG = "SUITE_RESULT "

BENCHMARKS: tuple[Benchmark, ...] = (
    Benchmark("ritter", "Ritter dry-bed dam break", "L1 of h per metre of width at t = 4 s [m²]",
              "ritter", (100, 200, 400, 800), ladders.ritter),
    Benchmark("stoker", "Stoker wet-bed dam break, depth ratio 10:1",
              "relative L1 of h at t = 2 s (then: the smallest depth, exact 0.1 m)", "stoker",
              (100, 200, 400, 800), ladders.stoker),
    Benchmark("stoker_100", "Stoker wet-bed dam break, depth ratio 100:1",
              "relative L1 of h at t = 2 s (then: the smallest depth, exact 0.01 m)", "stoker",
              (100, 200, 400, 800), ladders.stoker_100),
    Benchmark("thacker", "Thacker's planar surface in a paraboloid",
              "L1 of h after one period on the disc 0.2 m inside the wet/dry line [m³] "
              "(then: the whole domain, and the L1 on bands 0–0.25, 0.25–0.5, 0.5–0.8 m from "
              "the disc centre)", "thacker", (20, 40, 80, 160),
              ladders.thacker),
    Benchmark("thacker_2T", "Thacker's planar surface in a paraboloid, two periods",
              "as above, after two periods (8.97 s)", "thacker", (20, 40, 80),
              ladders.thacker_two_periods),
    Benchmark("mangeney", "Dam break on a Coulomb incline (Mangeney et al. 2000)",
              "L1 of h per metre of width at t = 2 s, where the upstream wall has not yet acted "
              "[m²]", "mangeney", (50, 100, 200, 400), ladders.mangeney),
    Benchmark("voellmy_sheet", "Voellmy sheet on a uniform slope",
              "relative error of the mean speed on 250 <= x <= 350 m at 3 relaxation times",
              "voellmy_sheet", (50, 100, 200, 400), ladders.voellmy_sheet, claims_order=False),
    Benchmark("shear_decay", "Viscous shear-mode decay (Bingham, τ_Y = 0)",
              "relative error of the decay rate after 1 s", "shear_decay", (10, 20, 40, 80),
              ladders.shear_decay),
    Benchmark("dam_break", "Inclined dam break (seed §4.1)",
              "relative error of the front (h > 1e-3 m) at 11 s against the exact tip "
              "(seed Table 1 measure)", "inclined_dam_break", (225, 450, 900), ladders.dam_break,
              claims_order=False),
    Benchmark("hemisphere", "Hemisphere collapse (seed §4.1.1)",
              "relative L1 error of h at 1.2 s against the converged radial solution",
              "hemisphere", (50, 100, 200), ladders.hemisphere, claims_order=False),
    Benchmark("lake_at_rest", "Lake at rest (seed §4.2), Voellmy + Bingham",
              "L1 of the free-surface error on wet nodes after 1 s [m³]", "lake_at_rest",
              (25, 50, 100), ladders.lake_at_rest, claims_order=False),
    Benchmark("voellmy_slope", "Slope form: Voellmy sheet on 35°",
              "relative error of the mean speed along the bed on 450 <= x <= 650 m at 3 "
              "relaxation times (exact sqrt(ξ h_n (sinθ − μ cosθ)) tanh(t/τ))", "slope",
              (100, 200, 400, 800), ladders.voellmy_slope),
    Benchmark("energy_line", "Slope form: Coulomb block from 35° onto a flat run-out",
              "|tan α / μ − 1| of the centre of mass at rest (energy line tan α = μ)",
              "slope", (200, 400, 800, 1600), ladders.energy_line),
    Benchmark("mangeney_slope", "Slope form: Mangeney's dam break on 30°",
              "L1 of h per metre of width at t = 2 s, where the upstream wall has not yet "
              "acted [m²]", "slope", (60, 120, 240, 480), ladders.mangeney_slope),
    Benchmark("manning_sheet", "Manning sheet on a uniform slope",
              "relative error of the mean speed on 250 <= x <= 350 m at 4 relaxation times "
              "(exact h^(2/3) S^(1/2)/n tanh(t/τ))", "manning_sheet", (50, 100, 200, 400),
              ladders.manning_sheet, claims_order=False),
    Benchmark("manning_slope", "Slope form: Manning sheet on 35°",
              "relative error of the mean speed along the bed on 450 <= x <= 650 m at 4 "
              "relaxation times (exact h_n^(2/3) (sinθ)^(1/2)/n tanh(t/τ))", "manning_sheet",
              (100, 200, 400, 800), ladders.manning_slope, claims_order=False),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the ``suite`` command."""
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks.md"))
    parser.add_argument("--figures", type=Path, default=Path("docs/figures"))
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these benchmarks")
    parser.add_argument("--levels", type=int, default=None, help="only the first N levels")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--methods", nargs="+", help="default: every registered method")
    parser.add_argument("--no-hard", action="store_true", help="skip the hard-case table")
    parser.add_argument("--timeout", type=float, default=1500.0, help="seconds per worker")
    parser.add_argument("--render", action="store_true",
                        help="rewrite the report from the raw results saved next to --out")
    parser.add_argument("--worker", metavar="NAME", help=argparse.SUPPRESS)
    parser.add_argument("--method", help=argparse.SUPPRESS)


def _benchmark(name: str) -> Benchmark:
    return next(b for b in BENCHMARKS if b.name == name)


def run_worker(args: argparse.Namespace) -> int:
    """Run one ladder (or the hard cases) for one method; print a JSON line per level."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    if args.worker == "hard":
        return _hard_worker(args.method, comm)
    bench = _benchmark(args.worker)
    bench.measure(bench.levels[0], args.method, comm)  # warm-up: JIT and form compilation
    for param in bench.levels[: args.levels]:
        level = bench.measure(param, args.method, comm)
        if comm.rank == 0:
            print(TAG + json.dumps(level.to_dict()), flush=True)
    return 0


def _hard_worker(method: str, comm) -> int:
    from dataclasses import asdict

    from fem_runout.bench.hard_cases import hard_case_files, run_hard_case
    from fem_runout.config import load_case

    for path in hard_case_files():
        res = run_hard_case(load_case(path, [("method", method)]), comm)
        if comm.rank == 0:
            print(TAG + json.dumps({"file": path.stem, **asdict(res)}), flush=True)
    return 0


def _launch(argv: list[str], ranks: int, timeout: float) -> list[dict[str, Any]]:
    exe = [sys.executable, "-m", "fem_runout.bench", "suite", *argv]
    if ranks > 1:
        exe = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks), *exe]
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run(exe, capture_output=True, text=True, timeout=timeout, env=env)
    rows = [json.loads(line[len(TAG):]) for line in proc.stdout.splitlines()
            if line.startswith(TAG)]
    if proc.returncode != 0:
        print(f"worker {' '.join(argv)} on {ranks} rank(s) failed:\n{proc.stderr[-2000:]}",
              file=sys.stderr, flush=True)
    return rows


def _methods(args: argparse.Namespace) -> list[str]:
    """Return the methods to run: ``--methods``, else every registered one (sorted by name)."""
    if args.methods:
        return list(args.methods)
    return sorted(method_names())


def run_driver(args: argparse.Namespace) -> int:
    """Run every ladder in workers and write the report."""
    from fem_runout.bench import suite_report

    start = time.perf_counter()
    benches = [b for b in BENCHMARKS if not args.only or b.name in args.only]
    if args.render:  # the report again, from the raw results of the last run
        raw = json.loads(args.out.with_suffix(".json").read_text())
        results = {b: {m: {int(k): v for k, v in r.items()} for m, r in by.items()}
                   for b, by in raw["results"].items()}
        benches = [b for b in benches if b.name in results]
        suite_report.write(benches, results, raw["hard"], args.out, args.figures, raw["total"])
        return 0
    results: dict[str, dict[str, dict[int, list[dict[str, Any]]]]] = {}
    for bench in benches:
        for method in _methods(args):
            for ranks in args.ranks:
                argv = ["--worker", bench.name, "--method", method]
                if args.levels:
                    argv += ["--levels", str(args.levels)]
                t0 = time.perf_counter()
                rows = _launch(argv, ranks, args.timeout)
                results.setdefault(bench.name, {}).setdefault(method, {})[ranks] = rows
                print(f"{bench.name} [{method}, {ranks} rank(s)]: {len(rows)} levels in "
                      f"{time.perf_counter() - t0:.0f} s", flush=True)
    hard = {} if args.no_hard else {
        m: _launch(["--worker", "hard", "--method", m], 1, args.timeout) for m in _methods(args)}
    total = time.perf_counter() - start
    raw = {"results": results, "hard": hard, "total": total}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.figures.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(raw, indent=1))
    text = suite_report.write(benches, results, hard, args.out, args.figures, total)
    print(f"wrote {args.out} ({len(text)} characters) in {total:.0f} s", flush=True)
    return 0


def main(args: argparse.Namespace) -> int:
    """Run the driver, or a worker with ``--worker``."""
    return run_worker(args) if args.worker else run_driver(args)
