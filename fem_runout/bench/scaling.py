"""Speed-up from 1 rank to R ranks, measured as users run a case (issue 16).

Usage::

    python -m fem_runout.bench scaling [--case cases/avakot.yaml] [--methods tg2 mpm]
                                       [--ranks 2] [--rounds 6] [--set KEY=VALUE ...]
                                       [--out docs/performance.md]

For each method, ``--rounds`` rounds of the case at 1 rank and at R ranks with the command line
(``python -m fem_runout``, outputs written as by users), in ABBA order: odd rounds run 1 rank
first, even rounds R ranks first. On a shared machine a run is slowed or sped up by the one
before it, and a fixed order biases the ratio (session 26 measured up to 20 %). Each run's
``wall_time`` (the time loop, from ``summary.json``) is reported per round with the round's
ratio, and the medians with their ratio. The run-out, the affected area and the step count must
be the same in every run of a method (the results do not depend on the rank count); the command
fails otherwise. The table goes between the ``<!-- scaling -->`` markers of the doc, with the
machine, the date and the command.

With ``--side-by-side`` every round also starts R copies of the 1-rank run at once, one per
core. How much slower each copy is than the run alone measures what the cores take from each
other (shared caches, memory bandwidth, a virtual machine's host): R runs of the same work at
once finish R ``t_1 / t_side`` times faster than R runs one after the other, the ceiling of
the speed-up on R ranks before any message or imbalance (session 37, a 2-vCPU Intel instance:
1.99–2.14×, no measurable slow-down; single pairs timed by hand had suggested 13–22 %, the
instance's drift). That ceiling takes the copies' mean; in brackets, the ceiling of an even
split, ``R t_1 / max(copies)``: the ranks of an evenly split run wait for the one on the
slowest core (session 45: one of two vCPUs ran the same 1-rank run 15 % slower than the other).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
from pathlib import Path
from typing import Any

from fem_runout.bench.markers import splice
from fem_runout.bench.real_case import ROOT, run_case, run_cases_together
from fem_runout.methods import method_names

__all__ = ["HELP", "SAME", "abba_order", "add_arguments", "format_table", "main", "summarize"]

HELP = "wall time at 1 and R ranks in ABBA rounds, the speed-up by medians (issue 16)"
BEGIN, END = "<!-- scaling -->", "<!-- /scaling -->"
#: Summary keys that must be the same in every run of a method, whatever its rank count.
SAME = ("runout_length", "affected_area", "steps")
#: How the run ended, reported beside the results (the first run's).
ENDING = ("t_end", "at_rest")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--case", type=Path, default=ROOT / "cases" / "avakot.yaml")
    parser.add_argument("--methods", nargs="+", default=method_names(), choices=method_names())
    parser.add_argument("--ranks", type=int, default=2, help="compared with 1 rank (>= 2)")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a case value in every run (repeatable)")
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "scaling",
                        help="output folders of the runs")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "performance.md",
                        help="doc with the <!-- scaling --> markers (left alone without them)")
    parser.add_argument("--side-by-side", action="store_true",
                        help="also run R copies of the 1-rank run at once in every round: the "
                             "speed-up's ceiling on this machine")


def abba_order(rounds: int, ranks: int) -> list[tuple[int, int]]:
    """Rank counts of every run in order: ``(1, R)`` in odd rounds, ``(R, 1)`` in even ones."""
    return [(1, ranks) if r % 2 == 0 else (ranks, 1) for r in range(rounds)]


def summarize(runs: list[dict[int, dict[str, Any]]]) -> dict[str, Any]:
    """Medians, ratios and the results' agreement of a method's rounds.

    Args:
        runs: One dict per round, rank count -> that run's ``summary.json``.

    Returns:
        ``walls`` (rank count -> the rounds' wall times), ``medians`` (rank count -> median),
        ``ratio`` (1-rank median over the other's), ``round_ratios``, ``same`` (whether every
        run has the same :data:`SAME` values) and ``result`` (the first run's values). With
        side-by-side runs (key ``"side"``: the summaries of the copies run at once) also
        ``side`` (the rounds' mean wall time of a copy), its median ``side_median`` and
        ``ceiling``, ``R`` times the 1-rank median over it; ``side_slowest`` (the rounds'
        slowest copy) and ``even_ceiling``, ``R`` times the 1-rank median over its median.
    """
    side = [r.get("side") for r in runs]
    runs = [{n: s for n, s in r.items() if n != "side"} for r in runs]
    counts = sorted(runs[0])
    walls = {n: [float(r[n]["wall_time"]) for r in runs] for n in counts}
    medians = {n: statistics.median(w) for n, w in walls.items()}
    many = counts[-1]
    first = {k: runs[0][counts[0]][k] for k in SAME + ENDING if k in runs[0][counts[0]]}
    copies = [c for r in side if r for c in r]
    same = all(s[k] == first[k] for r in runs for s in [*r.values(), *copies] for k in SAME)
    out = {"walls": walls, "medians": medians, "ratio": medians[1] / medians[many],
           "round_ratios": [w1 / wr for w1, wr in zip(walls[1], walls[many], strict=True)],
           "same": same, "result": first}
    if all(side):
        out["side"] = [statistics.fmean(float(c["wall_time"]) for c in r) for r in side]
        out["side_median"] = statistics.median(out["side"])
        out["ceiling"] = many * medians[1] / out["side_median"]
        out["side_slowest"] = [max(float(c["wall_time"]) for c in r) for r in side]
        out["even_ceiling"] = many * medians[1] / statistics.median(out["side_slowest"])
    return out


def _ending(result: dict[str, Any]) -> str:
    """Return the simulated time and how the run ended (at rest, or at its end or ``max``)."""
    if "t_end" not in result:
        return "–"
    how = "at rest" if result.get("at_rest") else "end or max"
    return f"{float(result['t_end']):.1f} ({how})"


def format_table(rows: dict[str, dict[str, Any]], ranks: int) -> str:
    """Markdown table: one row per method (the :func:`summarize` of its rounds).

    The per-round speed-ups (``t_1 / t_R`` of each ABBA round, whose two runs are minutes
    apart) are given as their range and median: on a machine whose speed drifts, the median of
    these paired ratios is less exposed to the drift than the ratio of the two medians.
    With side-by-side runs two more columns: a copy's wall time per round (the mean of the
    ``R`` copies) and the ceiling ``R t_1 / t_side`` by medians, with the even split's
    ceiling (the slowest copy's) in brackets.
    """
    side = all("side" in s for s in rows.values())
    extra = (f" {ranks} × 1 rank at once [s], per round | ceiling (even split) |", "---|---:|") \
        if side else ("", "")
    lines = [f"| method | 1 rank [s], per round | {ranks} ranks [s], per round | medians [s] | "
             f"speed-up by medians | per round (their median) |{extra[0]} run-out [m] | "
             "area [m²] | steps | "
             "simulated [s] | same result |",
             f"|---|---|---|---|---:|---|{extra[1]}---:|---:|---:|---|---|"]
    for method, s in rows.items():
        w1, wr = (", ".join(f"{t:.2f}" for t in s["walls"][n]) for n in (1, ranks))
        rr = s["round_ratios"]
        res = s["result"]
        more = (f" {', '.join(f'{t:.2f}' for t in s['side'])} | {s['ceiling']:.2f}× "
                f"({s['even_ceiling']:.2f}×) |" if side else "")
        lines.append(
            f"| {method} | {w1} | {wr} | {s['medians'][1]:.2f} / {s['medians'][ranks]:.2f} | "
            f"**{s['ratio']:.2f}×** | {min(rr):.2f}–{max(rr):.2f} "
            f"({statistics.median(rr):.2f}) |{more} "
            f"{res['runout_length']:.1f} | {res['affected_area']:.0f} | {res['steps']} | "
            f"{_ending(res)} | {'yes' if s['same'] else 'NO'} |")
    return "\n".join(lines)


def _machine() -> str:
    """CPU model (Linux) or the platform's processor name, and the core count."""
    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    return f"{model}, {os.cpu_count()} cores"


def _measure(args: argparse.Namespace, method: str) -> list[dict[int, dict[str, Any]]]:
    """Run a method's rounds in ABBA order; return each round's summaries by rank count."""
    extra = [a for item in args.set for a in ("--set", item)]
    runs = []
    for order in abba_order(args.rounds, args.ranks):
        round_ = {}
        for n in order:
            out = args.work / f"{method}_np{n}"
            run_case(args.case, method, n, out, extra)
            round_[n] = json.loads((out / "summary.json").read_text())
        if args.side_by_side:
            outs = [args.work / f"{method}_side{k}" for k in range(args.ranks)]
            run_cases_together(args.case, method, outs, extra)
            round_["side"] = [json.loads((o / "summary.json").read_text()) for o in outs]
        runs.append(round_)
    return runs


def main(args: argparse.Namespace) -> int:
    """Run the rounds of each method, print the table and write it into the doc."""
    if args.ranks < 2 or args.rounds < 1:
        raise SystemExit("--ranks must be at least 2 and --rounds at least 1")
    rows = {m: summarize(_measure(args, m)) for m in args.methods}
    table = format_table(rows, args.ranks)
    stamp = (f"{datetime.date.today()}, {_machine()}; `python -m fem_runout.bench scaling "
             f"--case {os.path.relpath(args.case, ROOT)} --methods {' '.join(args.methods)} "
             f"--ranks {args.ranks} --rounds {args.rounds}"
             + (" --side-by-side" if args.side_by_side else "")
             + "".join(f" --set {item}" for item in args.set) + "`")
    print(f"{table}\n\n{stamp}")
    splice(args.out, BEGIN, END, f"{table}\n\n{stamp}")
    if not all(s["same"] for s in rows.values()):
        print("the results differ between runs (see 'same result')")
        return 1
    return 0
