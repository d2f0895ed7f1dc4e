r"""Summarise finished ensembles (one per method) into docs/ensembles.md with their pictures.

Usage::

    python -m fem_runout.bench ensemble-report --run tg2=results/avakot_ensemble_tg2 \\
        --run mpm=results/avakot_ensemble_mpm --doc docs/ensembles.md --figures docs/figures

Reads each folder's ``members.csv`` and ``ensemble.json``; copies its pictures to
``<figures>/ensemble_<method>_<picture>.png`` and writes the table between the doc's
``<!-- avakot -->`` markers.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
from pathlib import Path

import numpy as np

from fem_runout.bench.markers import splice

__all__ = ["HELP", "add_arguments", "main", "method_rows"]

HELP = "summarise finished ensembles (members.csv, pictures) into docs/ensembles.md"
BEGIN, END = "<!-- avakot -->", "<!-- /avakot -->"
PICTURES = ("probability_depth", "peak_depth_percentiles", "distributions", "sensitivity")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--run", action="append", default=[], metavar="METHOD=DIR")
    parser.add_argument("--doc", type=Path, required=True)
    parser.add_argument("--figures", type=Path, required=True)


def _quantiles(values: list[float], scale: float = 1.0, fmt: str = "{:.0f}") -> str:
    q = np.percentile(np.asarray(values, dtype=float) * scale, (10, 50, 90))
    return " / ".join(fmt.format(v) for v in q)


def method_rows(method: str, folder: Path) -> tuple[str, list[str]]:
    """Return the method's summary table row and its sensitivity lines."""
    from fem_runout import methods

    with (folder / "members.csv").open() as f:
        members = list(csv.DictReader(f))
    ok = [m for m in members if not m["error"]]
    summary = json.loads((folder / "ensemble.json").read_text())
    walls = [float(m["wall_time"]) for m in ok]
    name = methods.get(method).display
    row = (f"| {name} | {len(members)} | {len(members) - len(ok)} | "
           f"{np.mean(walls):.1f} ({min(walls):.1f}–{max(walls):.1f}) | "
           f"{_quantiles([float(m['runout_length']) for m in ok])} | "
           f"{_quantiles([float(m['affected_area']) for m in ok], 1e-4, '{:.1f}')} | "
           f"{_quantiles([float(m['travel_angle_deg']) for m in ok], fmt='{:.1f}')} | "
           f"{_quantiles([float(m['peak_speed_max']) for m in ok], fmt='{:.1f}')} |")
    sens = summary.get("sensitivity", {}).get("runout_length", {})
    lines = [f"- {name}: Spearman correlation of the run-out with " +
             ", ".join(f"`{k}` {v:+.2f}" for k, v in sens.items())]
    return row, lines


def main(args: argparse.Namespace) -> int:
    """Write the table, the sensitivity lines and the pictures into the doc."""
    rows = ["| method | members | failed | loop wall per member [s], mean (range) | run-out "
            "[m] P10 / P50 / P90 | affected area [ha] P10 / P50 / P90 | travel angle [°] "
            "P10 / P50 / P90 | peak speed [m/s] P10 / P50 / P90 |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    notes, pictures = [], []
    args.figures.mkdir(parents=True, exist_ok=True)
    for spec in args.run:
        method, _, folder = spec.partition("=")
        row, lines = method_rows(method, Path(folder))
        rows.append(row)
        notes += lines
        for pic in PICTURES:
            target = args.figures / f"ensemble_{method}_{pic}.png"
            shutil.copyfile(Path(folder) / f"{pic}.png", target)
            rel = Path("figures") / target.name
            pictures.append(f"![{method}: {pic.replace('_', ' ')}]({rel.as_posix()})")
    body = "\n".join([*rows, "", *notes, "", *pictures])
    if not splice(args.doc, BEGIN, END, body):
        print(f"{args.doc} has no {BEGIN} markers: summary not written")
    print("\n".join(rows + notes))
    return 0
