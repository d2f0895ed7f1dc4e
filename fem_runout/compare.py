"""``python -m fem_runout compare CASE.yaml [--out DIR] [--overwrite] [--set k=v ...]``.

Runs one case with every registered method (:mod:`fem_runout.methods`), each
into ``<out>/<method>/``, and writes ``<out>/compare.md`` with side-by-side depth maps, the
depth difference, front position, volume balance and wall time of each method. Methods that are
not implemented yet get a column saying so. Exit codes as for a run: 0, 1, 2 (bad input), 3.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.errors import CaseError, SimulationError, first_error_everywhere
from fem_runout.methods import method_names

ALL_METHODS = method_names()


def build_parser() -> argparse.ArgumentParser:
    """Parser of the ``compare`` sub-command."""
    parser = argparse.ArgumentParser(
        prog="python -m fem_runout compare",
        description="Run one case with every implemented method and compare the results.")
    parser.add_argument("case", help="case file (YAML)")
    parser.add_argument("--out", metavar="DIR", help="output folder (results/compare/<name>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY.PATH=VALUE", help="override a case value (repeatable)")
    parser.add_argument("--overwrite", action="store_true", help="replace non-empty folders")
    return parser


def prepare(args: argparse.Namespace) -> tuple[Path, dict[str, Any]]:
    """Validate the case for each implemented method; raise CaseError on bad input."""
    from fem_runout.config import load_case

    base = load_case(args.case, list(args.overrides))
    out = Path(args.out) if args.out else Path("results/compare") / base.name
    if out.exists() and not out.is_dir():
        raise CaseError(f"output dir '{out}' exists and is not a directory")
    cases = {}
    for method in method_names():
        case = load_case(args.case, [*args.overrides, ("method", method),
                                     ("output.dir", str(out / method))])
        if case.output_dir.exists() and any(case.output_dir.iterdir()) and not args.overwrite:
            raise CaseError(f"output dir '{case.output_dir}' is not empty; pass --overwrite")
        cases[method] = case
    return out, cases


def difference(a, b) -> tuple[float, float]:
    """(L1, L∞) of ``h_a - h_b`` on the common node grid (lumped Q1 weights)."""
    from fem_runout.references.norms import l1, linf, nodal_weights

    d = a.h - b.h
    return l1(d, nodal_weights(a.x, a.y)), linf(d)


def _grid(r) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    nx = np.unique(np.round(r.x, 9)).size
    ny = r.x.size // nx
    return r.h.reshape(ny, nx), (r.x.min(), r.x.max(), r.y.min(), r.y.max())


def plot_fields(results: dict[str, Any], path: Path, title: str) -> None:
    """Plot the final depth of each method side by side, plus |h_a - h_b| when there are two."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    names = list(results)
    panels = len(names) + (1 if len(names) > 1 else 0)
    fig = Figure(figsize=(5 * panels, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(1, panels))
    vmax = max(float(r.h.max()) for r in results.values()) or 1.0
    for ax, name in zip(axes, names, strict=False):
        h, ext = _grid(results[name])
        aspect = "equal" if (ext[1] - ext[0]) <= 4 * (ext[3] - ext[2]) else "auto"
        im = ax.imshow(h, origin="lower", extent=ext, vmin=0, vmax=vmax, cmap="viridis",
                       aspect=aspect)
        ax.set_title(f"{name}: h at t = {results[name].t:.3g} s")
        fig.colorbar(im, ax=ax, label="h [m]")
    if len(names) > 1:
        a, b = results[names[0]], results[names[1]]
        (ha, ext), (hb, _) = _grid(a), _grid(b)
        im = axes[-1].imshow(np.abs(ha - hb), origin="lower", extent=ext, cmap="magma",
                             aspect=aspect)
        axes[-1].set_title(f"|h_{names[0]} − h_{names[1]}|")
        fig.colorbar(im, ax=axes[-1], label="[m]")
    fig.suptitle(title)
    fig.savefig(path, dpi=100)


def plot_series(results: dict[str, Any], path: Path, title: str) -> None:
    """Front position and volume balance over time, one line per method."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax_front, ax_mass = fig.subplots(1, 2)
    for name, r in results.items():
        s = r.series
        ax_front.plot(s["t"], s["front_x"], label=name)
        ax_mass.plot(s["t"], s["mass_error"], label=name)
    ax_front.set(xlabel="t [s]", ylabel="front x [m]", title="front position")
    ax_mass.set(xlabel="t [s]", ylabel="(V + outflow + dried − V0)/V0", title="volume balance")
    for ax in (ax_front, ax_mass):
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig.suptitle(title)
    fig.savefig(path, dpi=100)


def report(case_path: str, out: Path, results: dict[str, Any], ranks: int) -> str:
    """Return the markdown text of ``compare.md``."""
    lines = [f"# Comparison of methods on `{case_path}`", "",
             f"{ranks} MPI rank(s). Folders: " + ", ".join(f"`{out / m}/`" for m in results), "",
             "| | " + " | ".join(ALL_METHODS) + " |", "|---|" + "---:|" * len(ALL_METHODS)]
    rows = {"steps": lambda r: f"{r.steps}", "particles": lambda r: _particles(r),
            "wall time [s]": lambda r: f"{r.wall_time:.2f}", "final t [s]": lambda r: f"{r.t:.4g}",
            "final front x [m]": lambda r: f"{r.series['front_x'][-1]:.3f}",
            "max depth at end [m]": lambda r: f"{r.h.max():.4f}",
            "max relative volume error": lambda r: f"{np.abs(r.series['mass_error']).max():.2e}",
            "outflow [m³]": lambda r: f"{r.series['outflow'][-1]:.4g}",
            "dried films [m³]": lambda r: f"{r.series['dried'][-1]:.3g}"}
    for label, fmt in rows.items():
        cells = [fmt(results[m]) if m in results else "not implemented" for m in ALL_METHODS]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    names = list(results)
    if len(names) > 1:
        e1, einf = difference(results[names[0]], results[names[1]])
        lines += ["", f"Depth difference h_{names[0]} − h_{names[1]} at the end: "
                  f"L1 = {e1:.4g} m³, L∞ = {einf:.4g} m."]
    else:
        lines += ["", "Only one method is implemented: no depth difference."]
    lines += ["", "![depth](compare_fields.png)", "", "![series](compare_series.png)", ""]
    return "\n".join(lines)


def _particles(r) -> str:
    p = getattr(r, "particles", None)
    return "–" if p is None else f"{p}"


def _execute(args: argparse.Namespace, out: Path, cases: dict[str, Any], comm) -> None:
    from fem_runout.api import run

    results = {m: run(c, overwrite=args.overwrite, quiet=True, comm=comm)
               for m, c in cases.items()}
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        title = f"{next(iter(cases.values())).name}: " + " vs ".join(results)
        plot_fields(results, out / "compare_fields.png", title)
        plot_series(results, out / "compare_series.png", title)
        (out / "compare.md").write_text(report(args.case, out, results, comm.size))
        print(f"comparison written to {out / 'compare.md'}", flush=True)


def main(argv: list[str]) -> int:
    """Run the ``compare`` command; return the exit code (0, 1, 2, 3)."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    prepared: list = []
    if first_error_everywhere(comm, lambda: prepared.extend(prepare(args))):
        return 2
    out, cases = prepared
    try:
        _execute(args, out, cases, comm)
    except CaseError as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 2
    except SimulationError as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 3
    return 0
