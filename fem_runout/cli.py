"""Command line: ``python -m fem_runout CASE.yaml [--out DIR] [--method M] [--set k=v ...]``.

``python -m fem_runout compare CASE.yaml [--out DIR] [--overwrite]`` runs the case with every
implemented method and writes a side-by-side comparison (:mod:`fem_runout.compare`);
``python -m fem_runout ensemble CASE.yaml ENSEMBLE.yaml`` runs an ensemble
(:mod:`fem_runout.ensemble`).

Exit codes: 0 success, 1 unexpected failure, 2 bad input (case file, override, option,
output directory, checkpoint), 3 the simulation had to stop
(:class:`~fem_runout.errors.SimulationError`; the last good state is saved as a checkpoint),
4 an output could not be written (disk full, permission denied), 130/143 stopped by
SIGINT/SIGTERM (checkpoint and outputs written; restart with ``--restart``).
Input is fully validated before anything is written or any heavy module is imported.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fem_runout.errors import CaseError, RunInterrupted, SimulationError
from fem_runout.methods import method_names

if TYPE_CHECKING:
    from fem_runout.config import Case

__all__ = ["build_parser", "main"]

def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser."""
    parser = argparse.ArgumentParser(
        prog="python -m fem_runout",
        description="Simulate a landslide run-out described by a YAML case file.",
    )
    parser.add_argument("case", help="case file (YAML), e.g. cases/inclined_dam_break.yaml")
    parser.add_argument("--out", metavar="DIR", help="output directory (overrides output.dir)")
    parser.add_argument(
        "--method", choices=method_names(), help="numerical method (overrides method)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="override a case value, e.g. --set time.end=2 (repeatable; value read as YAML)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace a non-empty output directory"
    )
    parser.add_argument(
        "--restart", metavar="CHECKPOINT",
        help="continue from a checkpoint (<output.dir>/checkpoints/checkpoint_<step>.h5) on any "
        "number of ranks; the outputs continue in the same folder",
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    return parser


#: Seconds a rank waits between writing its last message and ``MPI_Abort`` (see _World.abort).
ABORT_GRACE = 0.5


class _World:
    """Rank and size of MPI_COMM_WORLD, with mpi4py imported only when available."""

    def __init__(self) -> None:
        try:
            from mpi4py import MPI
        except ImportError:  # pragma: no cover - mpi4py is a dependency
            self.comm: Any = None
            self.rank, self.size = 0, 1
        else:
            self.comm = MPI.COMM_WORLD
            self.rank, self.size = self.comm.rank, self.comm.size

    def first_error(self, message: str | None) -> str | None:
        """Return the first error any rank found (collective when running in parallel)."""
        if self.size == 1:
            return message
        messages = self.comm.allgather(message)
        return next((m for m in messages if m is not None), None)

    def say(self, message: str) -> None:
        """Print a one-line message to stderr on rank 0."""
        if self.rank == 0:
            print(message, file=sys.stderr, flush=True)

    def abort(self, code: int = 1) -> None:
        """Stop every rank when running in parallel.

        The streams are flushed and the launcher is given ``ABORT_GRACE`` seconds to forward
        them: mpich's hydra proxy may serve the abort before the lines this rank wrote just
        before it, and the job would end without its message (seen about once in 300 runs).
        """
        if self.size > 1:
            import time

            sys.stdout.flush()
            sys.stderr.flush()
            time.sleep(ABORT_GRACE)
            self.comm.Abort(code)

    def exit_now(self, code: int) -> None:
        """End the job with ``code`` at once.

        The failure may be on one rank only (MPI_Abort in parallel), and no destructor of a
        failed native writer may run (ADIOS2's would abort the process).
        """
        import os

        sys.stderr.flush()
        self.abort(code)
        os._exit(code)


def _check_output_dir(path: Path, overwrite: bool) -> None:
    """Refuse a non-empty output directory unless ``overwrite``; write nothing."""
    if not path.exists():
        return
    if not path.is_dir():
        raise CaseError(f"output dir '{path}' exists and is not a directory")
    if not overwrite and any(path.iterdir()):
        raise CaseError(f"output dir '{path}' is not empty; pass --overwrite to replace it")


def _prepare(args: argparse.Namespace) -> Case:
    """Load and check everything; raise CaseError for any bad input."""
    from fem_runout.config import load_case

    overrides: list[str | tuple[str, Any]] = list(args.overrides)
    if args.method is not None:
        overrides.append(("method", args.method))
    if args.out is not None:
        overrides.append(("output.dir", args.out))
    case = load_case(args.case, overrides)
    if args.restart is None:
        _check_output_dir(case.output_dir, args.overwrite)
    elif not Path(args.restart).is_file():
        raise CaseError(f"--restart: no checkpoint file '{args.restart}'")
    return case


def _run(case: Case, args: argparse.Namespace, world: _World) -> int:
    """Hand the case to ``fem_runout.api.run`` and map its outcome to an exit code."""
    try:
        from fem_runout.api import run
    except ImportError as exc:
        world.say(f"error: the runner fem_runout.api.run is not available ({exc})")
        return 1
    from fem_runout.signals import StopFlag

    stop = StopFlag().install()
    try:
        run(case, overwrite=args.overwrite, quiet=args.quiet, restart=args.restart, stop=stop)
    except CaseError as exc:
        world.say(f"error: {exc}")
        return 2
    except SimulationError as exc:
        world.say(f"error: {exc}")
        return 3
    except RunInterrupted as exc:
        world.say(f"{exc}")
        return 128 + exc.signum
    except OSError as exc:  # an output could not be written (disk full, permissions, ...)
        what = f"{exc.strerror}: {exc.filename}" if exc.strerror and exc.filename else str(exc)
        print(f"error: {what.removeprefix('error: ')}; the outputs written before it stay "
              "readable", file=sys.stderr, flush=True)
        world.exit_now(4)
    finally:
        stop.uninstall()
    return 0


def _report_crash(world: _World) -> int:
    """Print the current traceback with a rank prefix; abort the other ranks."""
    prefix = f"[rank {world.rank}] " if world.size > 1 else ""
    text = traceback.format_exc().rstrip("\n")
    print("\n".join(prefix + line for line in text.splitlines()), file=sys.stderr, flush=True)
    world.abort()
    return 1


#: ``python -m fem_runout <name> ...`` -> the module whose ``main(argv)`` runs it.
SUBCOMMANDS = {"compare": "fem_runout.compare", "ensemble": "fem_runout.ensemble.cli"}


def _subcommand(name: str, argv: list[str]) -> int:
    """Run a sub-command (exit codes as for a run; a crash stops every rank)."""
    import importlib

    world = _World()
    try:
        return importlib.import_module(SUBCOMMANDS[name]).main(argv)
    except Exception:
        return _report_crash(world)


def main(argv: list[str] | None = None) -> int:
    """Run the command line.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0 done, 1 unexpected failure, 2 bad input, 3 simulation stopped.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] and argv[0] in SUBCOMMANDS:
        return _subcommand(argv[0], argv[1:])
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help or a usage error (argparse already printed it)
        return exc.code if isinstance(exc.code, int) else 2
    world = _World()
    try:
        error: str | None = None
        case = None
        try:
            case = _prepare(args)
        except CaseError as exc:
            error = " ".join(str(exc).split("\n"))
        error = world.first_error(error)
        if error is not None or case is None:
            world.say(f"error: {error}")
            return 2
        return _run(case, args, world)
    except Exception:
        return _report_crash(world)
