"""Entry point: ``python -m fem_runout.bench COMMAND [options]`` (``--help`` lists commands)."""

from __future__ import annotations

import argparse
from types import ModuleType

from fem_runout.bench import (
    before_after,
    corridor_spread,
    dampm_report,
    dem_sampling,
    dry_sensitivity,
    ensemble_report,
    ensemble_throughput,
    footprint,
    meshes,
    peers,
    real_case,
    scaling,
    side_by_side,
    step_cost,
    suite,
    tg2_report,
)

COMMANDS: dict[str, ModuleType] = {
    "step-cost": step_cost,
    "suite": suite,
    "tg2-report": tg2_report,
    "dampm-report": dampm_report,
    "real-case": real_case,
    "dry-sensitivity": dry_sensitivity,
    "dem-sampling": dem_sampling,
    "before-after": before_after,
    "peers": peers,
    "footprint": footprint,
    "scaling": scaling,
    "meshes": meshes,
    "corridor-spread": corridor_spread,
    "side-by-side": side_by_side,
    "ensemble-throughput": ensemble_throughput,
    "ensemble-report": ensemble_report,
}
"""Command name -> module with ``HELP``, ``add_arguments(parser)`` and ``main(args)``."""


def build_parser() -> argparse.ArgumentParser:
    """Build the parser with one sub-command per benchmark."""
    parser = argparse.ArgumentParser(
        prog="python -m fem_runout.bench", description="fem_runout benchmarks."
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module in COMMANDS.items():
        command = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(command)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run a benchmark command.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit code: 0 done, 1 a benchmark failed, 2 usage error or no command given.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    return COMMANDS[args.command].main(args)


if __name__ == "__main__":
    raise SystemExit(main())
