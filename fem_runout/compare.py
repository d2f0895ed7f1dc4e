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
    """(L1, L∞) of ``h_a - h_b`` on the common nodes (lumped Q1 weights).

    Both runs are on the same mesh (the same case), so their gathered nodes match one to one.
    A rectangle's weights come from its node grid, any other mesh's are the runs' lumped mass.
    """
    from fem_runout.output import grid_shape
    from fem_runout.references.norms import l1, linf, nodal_weights

    d = a.h - b.h
    weights = nodal_weights(a.x, a.y) if grid_shape(a.x, a.y) is not None else a.area
    return l1(d, weights), linf(d)


Extent = tuple[float, float, float, float]


def _grid(r) -> tuple[np.ndarray, Extent]:
    nx = np.unique(np.round(r.x, 9)).size
    ny = r.x.size // nx
    return r.h.reshape(ny, nx), (r.x.min(), r.x.max(), r.y.min(), r.y.max())


def _image(r) -> tuple[np.ndarray, Extent] | None:
    """Return the final depth as an image (rows of increasing y), or None (scatter the nodes).

    A rectangle's node grid as it is; a gmsh mesh's depth as the run sampled it onto its
    raster (``deposit_depth.tif``, NaN outside the mesh), if it wrote one.
    """
    from fem_runout.output import grid_shape

    if grid_shape(r.x, r.y) is not None:
        return _grid(r)
    path = None if r.out_dir is None else Path(r.out_dir) / "deposit_depth.tif"
    if path is None or not path.is_file():
        return None
    import rasterio

    with rasterio.open(path) as src:
        data = src.read(1, masked=True).astype(np.float64).filled(np.nan)[::-1]
        b = src.bounds
    return data, (b.left, b.right, b.bottom, b.top)


def _panel(fig, ax, values, image, r, title, **style) -> None:
    """Draw one map: the image, or the nodes coloured by ``values`` (a mesh without raster)."""
    if image is not None:
        ext = image[1]
        aspect = "equal" if (ext[1] - ext[0]) <= 4 * (ext[3] - ext[2]) else "auto"
        art = ax.imshow(values, origin="lower", extent=ext, aspect=aspect, **style)
    else:
        art = ax.scatter(r.x, r.y, c=values, s=4, marker="s", linewidths=0, **style)
        ax.set_aspect("equal")
    ax.set_title(title)
    fig.colorbar(art, ax=ax, label="[m]" if "magma" in str(style.get("cmap")) else "h [m]")


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
    images = {name: _image(results[name]) for name in names}
    for ax, name in zip(axes, names, strict=False):
        r, image = results[name], images[name]
        _panel(fig, ax, r.h if image is None else image[0], image, r,
               f"{name}: h at t = {r.t:.3g} s", vmin=0, vmax=vmax, cmap="viridis")
    if len(names) > 1:
        (a, b), (ia, ib) = (results[n] for n in names[:2]), (images[n] for n in names[:2])
        both = ia is not None and ib is not None and ia[0].shape == ib[0].shape
        _panel(fig, axes[-1], np.abs(ia[0] - ib[0]) if both else np.abs(a.h - b.h),
               ia if both else None, a, f"|h_{names[0]} − h_{names[1]}|", cmap="magma")
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
