"""How much the real-terrain result depends on the dry tolerance and the thin-layer depth.

Usage::

    python -m fem_runout.bench dry-sensitivity [--methods tg2 mpm] [--ranks 2]
                                               [--case cases/avakot.yaml]
                                               [--doc docs/real_terrain.md]

For each method the case runs with its defaults, with ``numerics.dry_tolerance`` divided and
multiplied by 10, and with both the dry tolerance and ``numerics.thin_depth`` divided by 10
(κ ÷ 10), each with ``python -m fem_runout`` under ``mpiexec -n R`` into
``results/sensitivity_<method>_<k>``.
The table (peak speed, run-out, affected area, end, and the change against the default) is
printed and written between the doc's ``<!-- sensitivity -->`` markers.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from fem_runout.bench.markers import splice
from fem_runout.bench.real_case import ROOT, add_variant_arguments, run_case
from fem_runout.config import load_case
from fem_runout.methods import get

__all__ = ["HELP", "add_arguments", "main"]

HELP = "real-terrain result against the dry tolerance and thin-layer depth (÷10, ×10)"
BEGIN, END = "<!-- sensitivity -->", "<!-- /sensitivity -->"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    add_variant_arguments(parser)


def variants(case: Path) -> list[tuple[str, list[str]]]:
    """``(label, overrides)``: the default, dry tolerance ÷10 and ×10, both depths ÷10."""
    num = load_case(case).numerics
    dry, thin = num.dry_tolerance, num.thin_depth
    rows = [(f"default (dry {dry:g} m)", [])]
    rows.append((f"dry {dry / 10:g} m", [f"numerics.dry_tolerance={dry / 10!r}"]))
    rows.append((f"dry {dry * 10:g} m", [f"numerics.dry_tolerance={dry * 10:g}"]))
    thin = dry if thin is None else thin  # no thin_depth in the case: ÷10 of the dry tolerance
    rows.append((f"dry {dry / 10:g} m, thin_depth {thin / 10:g} m",
                 [f"numerics.dry_tolerance={dry / 10!r}", f"numerics.thin_depth={thin / 10!r}"]))
    return rows


def _row(method: str, label: str, s: dict[str, Any], ref: dict[str, Any] | None) -> str:
    speed, run, area = s["peak_speed_max"], s["runout_length"], s["affected_area"] / 1e4
    change = "–"
    if ref is not None:
        change = (f"speed {speed / ref['peak_speed_max'] - 1:+.2%}, "
                  f"run-out {run / ref['runout_length'] - 1:+.2%}, "
                  f"area {s['affected_area'] / ref['affected_area'] - 1:+.2%}")
    return (f"| {get(method).display} | {label} | {speed:.2f} | {run:.0f} | {area:.2f} | "
            f"{s['t_end']:.0f} | {s['at_rest']} | {change} |")


def main(args: argparse.Namespace) -> int:
    """Run every variant of every method, print and write the table."""
    lines = ["| method | numerics | peak speed [m/s] | run-out [m] | affected area [ha] | "
             "end [s] | at rest | change against the default |",
             "|---|---|---:|---:|---:|---:|---|---|"]
    for method in args.methods:
        ref = None
        for k, (label, overrides) in enumerate(variants(args.case)):
            out = ROOT / "results" / f"sensitivity_{method}_{k}"
            run_case(args.case, method, args.ranks, out,
                     [x for o in overrides for x in ("--set", o)])
            summary = json.loads((out / "summary.json").read_text())
            lines.append(_row(method, label, summary, ref))
            ref = ref or summary
    table = "\n".join(lines)
    print(table)
    if not splice(args.doc, BEGIN, END, table):  # the table is printed either way
        print(f"{args.doc} has no {BEGIN} markers: table not written")
    return 0
