r"""Ensemble throughput: the same members one after another on 1 rank, then side by side.

Usage::

    python -m fem_runout.bench ensemble-throughput cases/avakot.yaml cases/ensembles/avakot.yaml \\
        --members 8 --ranks 2 --set method=mpm --doc docs/ensembles.md

Each run is a fresh ``mpiexec -n R python -m fem_runout ensemble`` into its own folder (no
member is reused); the wall time is the whole command's. The table is printed and, with
``--doc``, written between the doc's ``<!-- throughput -->`` markers (appended to the rows
already there, so both methods can be measured in turn). The ensemble file is copied with
its keys in their order, so ``--members`` equal to the file's gives the file's members;
``--keep DIR`` keeps the side-by-side run's members and products.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from fem_runout.bench.markers import between, splice

__all__ = ["HELP", "add_arguments", "main"]

HELP = "ensemble wall time on 1 rank (members in turn) against N ranks (side by side)"
BEGIN, END = "<!-- throughput -->", "<!-- /throughput -->"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("case")
    parser.add_argument("ensemble")
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--doc", type=Path)
    parser.add_argument("--keep", type=Path,
                        help="move the side-by-side run's folder (members, products) here")


def _timed(ranks: int, case: str, spec: Path, out: Path, overrides: list[str]) -> float:
    mpiexec = Path(sys.executable).parent / "mpiexec"
    cmd = [str(mpiexec), "-n", str(ranks), sys.executable, "-m", "fem_runout", "ensemble",
           case, str(spec), "--out", str(out), "--quiet"]
    for item in overrides:
        cmd += ["--set", item]
    start = time.perf_counter()
    subprocess.run(cmd, check=True)
    return time.perf_counter() - start


def main(args: argparse.Namespace) -> int:
    """Run both, print the row, update the doc."""
    spec = yaml.safe_load(Path(args.ensemble).read_text())
    spec["members"] = args.members
    work = Path(tempfile.mkdtemp(prefix="ensemble_throughput_"))
    try:
        spec_path = work / "ensemble.yaml"
        spec_path.write_text(yaml.safe_dump(spec, sort_keys=False))  # the file's order of
        one = _timed(1, args.case, spec_path, work / "one", args.overrides)  # `vary`: members
        many = _timed(args.ranks, args.case, spec_path, work / "many", args.overrides)
        if args.keep is not None:
            shutil.rmtree(args.keep, ignore_errors=True)
            shutil.move(work / "many", args.keep)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    row = (f"| {Path(args.case).name} {' '.join(args.overrides)} | {args.members} | {one:.1f} | "
           f"{args.ranks} | {many:.1f} | {many / one:.2f} |")
    print(row)
    if args.doc is not None:
        rows = [r for r in (between(args.doc.read_text(), BEGIN, END) or "").strip()
                .splitlines() if r.strip()]
        if not rows:
            rows = ["| case | members | 1 rank, in turn [s] | ranks | side by side [s] | ratio |",
                    "|---|---:|---:|---:|---:|---:|"]
        if not splice(args.doc, BEGIN, END, "\n".join([*rows, row])):
            print(f"{args.doc} has no {BEGIN} markers: row not written")
    return 0
