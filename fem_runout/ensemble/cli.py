"""``python -m fem_runout ensemble CASE.yaml ENSEMBLE.yaml [--out DIR] [--set k=v ...]``.

Exit codes as for a run: 0 done, 1 unexpected failure, 2 bad input (case, ensemble file,
override); nothing is written before every member's case is validated.
"""

from __future__ import annotations

import argparse
import sys

from fem_runout.errors import first_error_everywhere

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of the ``ensemble`` sub-command."""
    parser = argparse.ArgumentParser(
        prog="python -m fem_runout ensemble",
        description="Run an ensemble of a case (parameters sampled from distributions) and "
        "write probability, percentile and sensitivity products.")
    parser.add_argument("case", help="case file (YAML)")
    parser.add_argument("ensemble", help="ensemble file (YAML), e.g. cases/ensembles/avakot.yaml")
    parser.add_argument("--out", metavar="DIR", help="ensemble folder (overrides output.dir)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY.PATH=VALUE", help="override a base-case value (repeatable)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return parser


def main(argv: list[str]) -> int:
    """Run the sub-command; return the exit code."""
    from mpi4py import MPI

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    comm = MPI.COMM_WORLD
    from fem_runout.ensemble.driver import prepare, run_ensemble

    plans: list = []
    if first_error_everywhere(comm, lambda: plans.append(prepare(args.case, args.ensemble,
                                                                 args.overrides, args.out))):
        return 2
    result = run_ensemble(args.case, args.ensemble, overrides=args.overrides, out=args.out,
                          comm=comm, quiet=args.quiet, plan=plans[0])
    if comm.rank == 0 and not args.quiet:
        s = result.summary
        print(f"ensemble: {s['members']} members ({result.ran} run now, {s['failed']} failed); "
              f"products in {result.out}/", file=sys.stderr)
    return 0
