"""Run the real-terrain case (``cases/avakot.yaml``) and write its results into the docs.

Usage::

    python -m fem_runout.bench real-case [--method tg2] [--ranks 1 2] [--case cases/avakot.yaml]
                                         [--doc docs/real_terrain.md] [--collect]

For each rank count the case runs with ``python -m fem_runout`` (under ``mpiexec -n R`` for
R > 1) into ``results/<name>_<method>_np<R>``. Each run's ``summary.json`` becomes a row of
``docs/real_terrain_results.json`` (rows of other methods are kept), the table between the
``<!-- results -->`` markers of the doc is regenerated from all rows, and the hazard map PNG of
the run with the most ranks is copied to ``docs/figures/<name>_<method>.png`` (and its 3-D
deposit view to ``<name>_<method>_3d.png``). With
``--collect`` nothing runs: the existing result folders are read.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from fem_runout.bench.markers import splice
from fem_runout.methods import default_method, method_names

__all__ = ["HELP", "add_arguments", "add_variant_arguments", "format_table", "main",
           "run_case"]

HELP = "run the real-terrain case with a method at 1 and 2 ranks; update docs/real_terrain.md"
ROOT = Path(__file__).resolve().parents[2]
BEGIN, END = "<!-- results -->", "<!-- /results -->"
COLUMNS = (
    ("method", "method", "{}"), ("ranks", "ranks", "{}"),
    ("runout_length", "run-out length [m]", "{:.0f}"),
    ("travel_angle_deg", "travel angle [°]", "{:.1f}"),
    ("affected_area", "affected area [m²]", "{:.0f}"),
    ("peak_depth_max", "peak depth [m]", "{:.2f}"),
    ("peak_speed_max", "peak speed [m/s]", "{:.1f}"),
    ("deposit_volume", "deposit volume [m³]", "{:.1f}"),
    ("outflow_volume", "outflow [m³]", "{:.3g}"),
    ("dried_volume", "dried films [m³]", "{:.3g}"),
    ("mass_balance_error", "volume balance error", "{:.1e}"),
    ("t_end", "end time [s]", "{:.1f}"),
    ("at_rest", "at rest", "{}"),
    ("steps", "steps", "{}"),
    ("wall_time", "wall time [s]", "{:.0f}"),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--method", default=default_method(), choices=method_names())
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--case", type=Path, default=ROOT / "cases" / "avakot.yaml")
    parser.add_argument("--doc", type=Path, default=ROOT / "docs" / "real_terrain.md")
    parser.add_argument("--collect", action="store_true",
                        help="do not run; read the existing result folders")


def add_variant_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the benches that run variants of the real-terrain case.

    ``--methods`` (all), ``--ranks`` (2), ``--case`` (cases/avakot.yaml) and ``--doc``
    (docs/real_terrain.md, where the bench writes its table).
    """
    parser.add_argument("--methods", nargs="+", default=method_names(), choices=method_names())
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--case", type=Path, default=ROOT / "cases" / "avakot.yaml")
    parser.add_argument("--doc", type=Path, default=ROOT / "docs" / "real_terrain.md")


def _out_dir(name: str, method: str, ranks: int) -> Path:
    return ROOT / "results" / f"{name}_{method}_np{ranks}"


def _command(case: Path, method: str, ranks: int, out: Path, extra: Sequence[str]) -> list[str]:
    """Return the command line of a run (``mpiexec`` for more than one rank)."""
    cmd = [sys.executable, "-m", "fem_runout", str(case), "--method", method, "--out",
           str(out), "--overwrite", "--quiet", *extra]
    if ranks > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(ranks), *cmd]
    return cmd


def _env() -> dict[str, str]:
    return dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")


def run_case(case: Path, method: str, ranks: int, out: Path, extra: Sequence[str] = ()) -> None:
    """Run the case with the command line (one thread per rank; ``extra`` arguments)."""
    subprocess.run(_command(case, method, ranks, out, extra), check=True, cwd=ROOT, env=_env())


def run_cases_together(case: Path, method: str, outs: Sequence[Path],
                       extra: Sequence[str] = ()) -> None:
    """Start one 1-rank run per folder of ``outs`` at once and wait for all of them."""
    procs = [subprocess.Popen(_command(case, method, 1, out, extra), cwd=ROOT, env=_env())
             for out in outs]
    codes = [p.wait() for p in procs]  # wait for every copy before reporting one
    failed = [(code, p.args) for code, p in zip(codes, procs, strict=True) if code != 0]
    if failed:
        raise subprocess.CalledProcessError(*failed[0])


def format_table(rows: list[dict[str, Any]]) -> str:
    """Markdown table of the result rows (sorted by method, then ranks)."""
    head = "| " + " | ".join(label for _, label, _ in COLUMNS) + " |"
    rule = "|" + "|".join("---:" for _ in COLUMNS) + "|"
    lines = [head, rule]
    for row in sorted(rows, key=lambda r: (r["method"], r["ranks"])):
        cells = [fmt.format(row[key]) if key in row else "–" for key, _, fmt in COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _update_doc(doc: Path, table: str) -> None:
    if not splice(doc, BEGIN, END, table):
        raise SystemExit(f"{doc} has no {BEGIN} ... {END} markers")


def main(args: argparse.Namespace) -> int:
    """Run (or collect) the case for each rank count and update the doc."""
    name = args.case.stem
    store = args.doc.with_name(args.doc.stem + "_results.json")
    rows = json.loads(store.read_text()) if store.exists() else []
    rows = [r for r in rows if not (r["method"] == args.method and r["ranks"] in args.ranks)]
    for ranks in args.ranks:
        out = _out_dir(name, args.method, ranks)
        if not args.collect:
            run_case(args.case, args.method, ranks, out)
        summary = json.loads((out / "summary.json").read_text())
        rows.append({key: summary[key] for key, _, _ in COLUMNS if key in summary})
    store.write_text(json.dumps(rows, indent=1) + "\n")
    figures = args.doc.parent / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    source = _out_dir(name, args.method, max(args.ranks))
    shutil.copyfile(source / "hazard_map.png", figures / f"{name}_{args.method}.png")
    shutil.copyfile(source / "deposit_3d.png", figures / f"{name}_{args.method}_3d.png")
    _update_doc(args.doc, format_table(rows))
    print(format_table(rows))
    return 0
