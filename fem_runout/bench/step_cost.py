"""Wall time per step on N x N meshes (TG2-PC or DAMPM), serially and on 2 MPI ranks.

Usage::

    python -m fem_runout.bench step-cost [--cells 250 ...] [--steps 30] [--ranks 1 2]
                                         [--method tg2|mpm] [--set KEY=VALUE ...]
                                         [--out docs/step_cost.md] [--profile]

The driver does not import dolfinx. For each rank count it starts a worker,
``python -m fem_runout.bench step-cost --worker`` (serially for 1 rank, under
``mpiexec -n R`` otherwise), with one thread per rank. A worker runs
``cases/hemisphere.yaml`` on an N x N mesh through the one run function
(:func:`fem_runout.api.run`, no output written) for 3 warm-up steps (numba JIT, form
compilation) and ``--steps`` timed steps; a :class:`StepTimer` callback adds up the solver's
share of each step (``stable_dt`` and ``advance``, as the runner measures it) and rank 0
prints one ``STEP_COST_RESULT {json}`` line: the maximum over ranks of the mean wall time per
step. The driver writes the markdown table to ``--out``.
"""

from __future__ import annotations

import argparse
import cProfile
import datetime
import io
import json
import os
import platform
import pstats
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from fem_runout.methods import METHODS, default_method, method_names

__all__ = ["HELP", "StepTimer", "add_arguments", "format_report", "machine_info", "main"]

HELP = "wall time per step on N x N meshes, TG2-PC or DAMPM (serial and 2 MPI ranks)"
RESULT_TAG = "STEP_COST_RESULT "
WARMUP_STEPS = 3
PROFILE_TOP = 15
DEFAULT_CASE = Path(__file__).resolve().parents[2] / "cases" / "hemisphere.yaml"
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")
FAR = 1e6  # end time [s] far beyond the timed steps (the step count ends the run)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``step-cost`` options to ``parser``."""
    parser.add_argument("--cells", type=int, nargs="+", default=[250], metavar="N",
                        help="N x N cells, one or more N (250)")
    parser.add_argument("--method", choices=method_names(), default=default_method(),
                        help=f"method ({default_method()})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="case override (repeatable)")
    parser.add_argument("--steps", type=int, default=30, help="timed steps per run (30)")
    parser.add_argument(
        "--out", type=Path, default=Path("docs/step_cost.md"), help="markdown report to write"
    )
    parser.add_argument(
        "--ranks", type=int, nargs="+", default=[1, 2], help="MPI rank counts to run (1 2)"
    )
    parser.add_argument(
        "--case", type=Path, default=DEFAULT_CASE, help="case file (default cases/hemisphere.yaml)"
    )
    parser.add_argument(
        "--profile", action="store_true", help="also print a cProfile top-15 of rank 0"
    )
    parser.add_argument(
        "--timeout", type=float, default=1800.0, help="seconds allowed per worker (1800)"
    )
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def main(args: argparse.Namespace) -> int:
    """Run the driver, or a worker with ``--worker``; return the exit code."""
    if min(args.cells) < 1 or args.steps < 1 or any(r < 1 for r in args.ranks):
        print("error: --cells, --steps and --ranks must be positive", file=sys.stderr)
        return 2
    if not args.case.is_file():
        print(f"error: case file '{args.case}' does not exist", file=sys.stderr)
        return 2
    return run_worker(args) if args.worker else run_driver(args)


# --- worker (runs under MPI, imports dolfinx) ---------------------------------------------


class StepTimer:
    """Callback: mean wall time of the solver's steps after a warm-up, max over ranks.

    Times what the runner reports as the solver's share of each step
    (:attr:`~fem_runout.callbacks.StepInfo.solver_seconds`: ``stable_dt`` and ``advance``),
    not the diagnostics and outputs; optionally profiles ``steps`` more steps on rank 0.

    Args:
        warmup: Steps before timing (numba JIT, form compilation).
        steps: Timed steps.
        profile: Profile ``steps`` more steps with cProfile on rank 0.
    """

    def __init__(self, warmup: int, steps: int, profile: bool = False) -> None:
        self.warmup, self.steps, self.profile = warmup, steps, profile
        self.seconds = 0.0
        self.particles: int | None = None
        self.report: str | None = None
        self._profiler: cProfile.Profile | None = None

    def start(self, solver: Any, info: Any) -> None:
        """Nothing before the first step."""

    def step(self, solver: Any, info: Any) -> None:
        """Add up the solver time of the timed steps; start the profiler after them."""
        if self.warmup < info.step <= self.warmup + self.steps:
            self.seconds += info.solver_seconds
        if info.step == self.warmup + self.steps and self.profile and solver.comm.rank == 0:
            self._profiler = cProfile.Profile()
            self._profiler.enable()

    def output(self, solver: Any, info: Any) -> None:
        """Nothing at outputs."""

    def finish(self, solver: Any, info: Any) -> None:
        """Reduce the mean over ranks (collective) and stop the profiler."""
        from mpi4py import MPI

        self.seconds = solver.comm.allreduce(self.seconds / self.steps, op=MPI.MAX)
        self.particles = solver.n_particles  # collective
        if self._profiler is not None:
            self._profiler.disable()
            text = io.StringIO()
            pstats.Stats(self._profiler, stream=text).sort_stats("tottime").print_stats(
                PROFILE_TOP)
            self.report = text.getvalue()


def run_worker(args: argparse.Namespace) -> int:
    """Run the case through :func:`fem_runout.api.run` with a :class:`StepTimer`.

    The case runs on ``N x N`` cells for the warm-up, timed (and profiled) steps, with one
    output at the end; rank 0 prints the result line.
    """
    from mpi4py import MPI

    # isort: split

    import dolfinx

    from fem_runout.api import run
    from fem_runout.config import load_case

    comm = MPI.COMM_WORLD
    n = args.cells[0]
    total = WARMUP_STEPS + args.steps * (2 if args.profile else 1)
    case = load_case(args.case, overrides=[
        f"domain.cells=[{n},{n}]", f"method={args.method}", *args.set, f"time.end={FAR}",
        f"output.every={FAR}", f"time.max_steps={total}"])
    timer = StepTimer(WARMUP_STEPS, args.steps, args.profile)
    run(case, write=False, comm=comm, callbacks=[timer])
    if comm.rank == 0:
        if timer.report is not None:
            print(f"cProfile of rank 0 of {comm.size}, {args.steps} steps:\n{timer.report}",
                  flush=True)
        result = {
            "ranks": comm.size,
            "n": n,
            "cells": n**2,
            "method": args.method,
            "particles": timer.particles,
            "steps": args.steps,
            "seconds_per_step": timer.seconds,
            "dolfinx": dolfinx.__version__,
        }
        print(RESULT_TAG + json.dumps(result), flush=True)
    return 0


# --- driver (no dolfinx) -------------------------------------------------------------------


def _mpiexec() -> str:
    """Return the ``mpiexec`` next to the running Python (the venv's), else the one on PATH."""
    local = Path(sys.executable).parent / "mpiexec"
    if local.exists():
        return str(local)
    found = shutil.which("mpiexec")
    if found is None:
        raise RuntimeError("mpiexec not found next to python or on PATH")
    return found


def worker_command(ranks: int, args: argparse.Namespace, n: int) -> list[str]:
    """Return the command line of a worker on ``ranks`` ranks and ``n`` x ``n`` cells."""
    command = [sys.executable, "-m", "fem_runout.bench", "step-cost", "--worker"]
    command += ["--cells", str(n), "--steps", str(args.steps), "--method", args.method]
    for item in args.set:
        command += ["--set", item]
    command += ["--case", str(args.case.resolve())]
    if args.profile:
        command.append("--profile")
    return command if ranks == 1 else [_mpiexec(), "-n", str(ranks), *command]


def run_one(ranks: int, args: argparse.Namespace, n: int) -> dict[str, Any]:
    """Run a worker on ``ranks`` ranks and ``n`` x ``n`` cells; return its result.

    Raises:
        RuntimeError: If the worker fails or prints no result.
    """
    env = {**os.environ, **dict.fromkeys(THREAD_VARIABLES, "1")}
    command = worker_command(ranks, args, n)
    done = subprocess.run(
        command, env=env, stdout=subprocess.PIPE, text=True, timeout=args.timeout, check=False
    )
    result = None
    for line in done.stdout.splitlines():
        if line.startswith(RESULT_TAG):
            result = json.loads(line[len(RESULT_TAG) :])
        else:
            print(line)
    if done.returncode != 0 or result is None:
        raise RuntimeError(f"worker failed (exit {done.returncode}): {' '.join(command)}")
    return result


def cpu_model() -> str:
    """Return the CPU model name (``lscpu``, then ``/proc/cpuinfo``, then ``platform``)."""
    try:
        lines = subprocess.run(
            ["lscpu"],
            capture_output=True,
            text=True,
            check=False,
            timeout=10,
            env={**os.environ, "LC_ALL": "C"},
        ).stdout.splitlines()
    except (OSError, subprocess.SubprocessError):
        lines = []
    try:
        lines += Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        pass
    for line in lines:
        key, _, value = line.partition(":")
        if key.strip().lower() in ("model name", "model name:") and value.strip():
            return value.strip()
    return platform.processor() or platform.machine() or "unknown"


def machine_info() -> dict[str, Any]:
    """CPU model, cores available to this process, date, Python and OS."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cores = os.cpu_count() or 0
    return {
        "cpu": cpu_model(),
        "cores": cores,
        "date": datetime.date.today().isoformat(),
        "python": platform.python_version(),
        "system": f"{platform.system()} {platform.machine()}",
    }


def format_report(results: list[dict[str, Any]], machine: dict[str, Any], case: str) -> str:
    """Return the markdown report: the table, then the machine and how it was measured."""
    steps, method = results[0]["steps"], results[0].get("method", default_method())
    sizes = " ".join(sorted({str(r["n"]) for r in results}, key=int))
    rows = [
        "| ranks | cells | particles | ms/step | µs/cell/step | µs/particle/step |",
        "|------:|------:|----------:|--------:|-------------:|-----------------:|",
    ]
    for r in results:
        ms, us = 1e3 * r["seconds_per_step"], 1e6 * r["seconds_per_step"] / r["cells"]
        npart = r.get("particles")
        per_p = f"{1e6 * r['seconds_per_step'] / npart:.3f}" if npart else "–"
        rows.append(f"| {r['ranks']} | {r['cells']} | {npart or '–'} | {ms:.1f} | {us:.3f} | "
                    f"{per_p} |")
    ranks = " ".join(sorted({str(r["ranks"]) for r in results}, key=int))
    title = METHODS[method].display if method in METHODS else method
    sets = "".join(f" --set '{item}'" for item in results[0].get("overrides", []))
    return "\n".join(
        [
            f"# {title} cost per time step",
            "",
            *rows,
            "",
            f"Machine: {machine['cpu']}, {machine['cores']} cores available, {machine['system']}; "
            f"date {machine['date']}; DOLFINx {results[0]['dolfinx']}, Python {machine['python']}; "
            "one thread per rank.",
            "",
            "## How it is measured",
            "",
            f"Case `{case}` on N x N meshes (N = {sizes}). Each rank count runs in a fresh "
            f"process (`mpiexec -n R` for R > 1) and runs the case through the one run "
            f"function (`fem_runout.api.run`, nothing written): {WARMUP_STEPS} warm-up steps "
            f"(numba JIT, form compilation), then {steps} timed steps; the time of a step is "
            "the solver's part as the runner measures it (`stable_dt` and `advance`), not the "
            "diagnostics. "
            "ms/step is the maximum over ranks of the mean wall time per step; µs/cell/step is "
            "that time divided by the total number of cells (not per rank).",
            "",
            "Reproduce (add `--profile` for a cProfile top-15 of rank 0):",
            "",
            "```bash",
            f".venv/bin/python -m fem_runout.bench step-cost --method {method} --cells {sizes} "
            f"--steps {steps} --ranks {ranks}{sets}",
            "```",
            "",
        ]
    )


def _display_path(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def run_driver(args: argparse.Namespace) -> int:
    """Run every rank count, print and write the report."""
    results = []
    for n in args.cells:
        for ranks in args.ranks:
            print(f"step-cost: {args.method}, {ranks} rank(s), {n} x {n} cells ...", flush=True)
            try:
                results.append({**run_one(ranks, args, n), "overrides": args.set})
            except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
                print(f"error: {exc}", file=sys.stderr)
                return 1
    report = format_report(results, machine_info(), _display_path(args.case))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report, encoding="utf-8")
    print(report.split("\n## ")[0].rstrip())
    print(f"\nwritten to {args.out}")
    return 0
