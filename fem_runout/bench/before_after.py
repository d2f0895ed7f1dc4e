"""Compare two ``benchmarks.json`` files level by level (accuracy and steps before/after).

Usage::

    python -m fem_runout.bench before-after OLD.json NEW.json [--out docs/x.md] [--title T]

For every ladder, method and level that both files hold (1-rank runs), one row with the error
before and after, their ratio, and the step counts; the last column flags a level whose error
grew by more than ``--tolerance`` (10 % by default).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["HELP", "add_arguments", "main", "table"]

HELP = "error and steps of two benchmarks.json files, level by level"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--out", type=Path, help="write the markdown table here")
    parser.add_argument("--tolerance", type=float, default=0.10)


def table(old: dict, new: dict, tolerance: float = 0.10) -> tuple[str, int]:
    """Markdown table and the number of levels whose error grew by more than ``tolerance``."""
    lines = ["| ladder | method | level | error before | error after | after / before | "
             "steps before | steps after | |", "|---|---|---|---:|---:|---:|---:|---:|---|"]
    worse = 0
    for name, by_method in new["results"].items():
        for method, by_ranks in by_method.items():
            before = {r["level"]: r for r in old["results"].get(name, {}).get(method, {})
                      .get("1", [])}
            for row in by_ranks.get("1", []):
                prev = before.get(row["level"])
                if prev is None:
                    continue
                e0, e1 = prev["error"], row["error"]
                ratio = e1 / e0 if e0 else (1.0 if e1 == 0 else float("inf"))
                flag = ""
                if e0 and ratio > 1.0 + tolerance:
                    flag, worse = "worse", worse + 1
                lines.append(f"| {name} | {method} | {row['level']} | {e0:.4g} | {e1:.4g} | "
                             f"{ratio:.3f} | {prev['steps']} | {row['steps']} | {flag} |")
    return "\n".join(lines) + "\n", worse


def main(args: argparse.Namespace) -> int:
    """Print (and write) the table."""
    text, worse = table(json.loads(args.old.read_text()), json.loads(args.new.read_text()),
                        args.tolerance)
    if args.out:
        args.out.write_text(text)
    print(text)
    print(f"{worse} level(s) more than {args.tolerance:.0%} worse")
    return 0
