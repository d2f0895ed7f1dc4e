"""Markdown report and figures of the benchmark suite (``docs/benchmarks.md``).

Method names, display names, figure markers and the paper's values come from the registry
(:mod:`fem_runout.methods`); the results are keyed by method name.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from fem_runout.bench.ladders import Benchmark
from fem_runout.bench.references_text import PAPER_TABLE1, READING, REFERENCES
from fem_runout.bench.step_cost import machine_info
from fem_runout.methods import METHODS, default_method, method_names

Rows = list[dict[str, Any]]
#: Matplotlib (colour, marker) of a method missing from the registry.
UNKNOWN_MARKER = ("k", "^")


def _fmt(v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return "0" if v == 0 else (f"{v:.4g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.3e}")
    return str(v)


def orders(errors: list[float]) -> list[float | None]:
    """Observed orders ``log2(e_{k-1}/e_k)`` (the ladders halve the cell size)."""
    out: list[float | None] = [None]
    for a, b in zip(errors[:-1], errors[1:], strict=True):
        out.append(math.log2(a / b) if a > 0 and b > 0 else None)
    return out


def ladder_table(bench: Benchmark, by_ranks: dict[int, Rows]) -> list[str]:
    """One method's ladder: level, cells, particles, steps, wall (1/2 ranks), error, order."""
    serial = by_ranks.get(1) or next(iter(by_ranks.values()), [])
    par = {r["level"]: r for r in by_ranks.get(2, [])}
    extra = list(serial[0]["extra"]) if serial else []
    head = ["level", "cells", "particles", "steps", "wall 1 rank [s]", "wall 2 ranks [s]",
            "error", *(["order"] if bench.claims_order else []), *extra]
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    for row, order in zip(serial, orders([r["error"] for r in serial]), strict=True):
        p = par.get(row["level"])
        cells = [row["level"], row["cells"], row["particles"], row["steps"], row["wall"],
                 p["wall"] if p else None, row["error"],
                 *([None if order is None else round(order, 2)] if bench.claims_order else []),
                 *(row["extra"][k] for k in extra)]
        lines.append("| " + " | ".join(_fmt(c) for c in cells) + " |")
    return lines


def plot(bench: Benchmark, by_method: dict[str, dict[int, Rows]], path: Path,
         stamp: str) -> bool:
    """Error against wall time, log-log, every method on the same axes; False if nothing > 0."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    drawn = False
    for method, by_ranks in by_method.items():
        color, marker = METHODS[method].marker if method in METHODS else UNKNOWN_MARKER
        for ranks, style in ((1, "-"), (2, "--")):
            pts = [(r["wall"], r["error"]) for r in by_ranks.get(ranks, [])
                   if r["error"] > 0 and r["wall"] > 0]
            if pts:
                ax.loglog(*zip(*pts, strict=True), style, color=color, marker=marker,
                          label=f"{method}, {ranks} rank{'s' if ranks > 1 else ''}")
                drawn = True
    if not drawn:
        return False
    ax.set(xlabel="wall time of the time loop [s]", ylabel="error", title=bench.title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.text(0.01, 0.005, stamp, fontsize=6, color="0.4")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    return True


def _table1(results: dict) -> list[str]:
    from fem_runout.references.inclined_dam_break import exact_front

    lines = ["### Seed Table 1 with our numbers", "",
             "Relative front error |x_f − x_exact|/x_exact, x_exact = exact dry-bed tip "
             f"({exact_front(5.5):.1f} m at 5.5 s, {exact_front(11.0):.1f} m at 11 s); "
             "front positions in brackets.", "",
             "| method | level | T = 5.5 s | T = 11 s |", "|---|---|---:|---:|"]
    for method, (e55, e11, f55, f11) in PAPER_TABLE1.items():
        lines.append(f"| {method} | paper | {e55} ({f55} m) | {e11} ({f11} m) |")
    for method, by_ranks in results.get("dam_break", {}).items():
        for r in by_ranks.get(1, []):
            x = r["extra"]
            lines.append(f"| {method} (ours) | {r['level']} | {x['rel_5_5']:.4f} "
                         f"({x['front_5_5']:.1f} m) | {r['error']:.4f} "
                         f"({x['front_11']:.1f} m) |")
    return lines + [""]


def _table2(results: dict) -> list[str]:
    """Seed Table 2: the paper's (L1, L∞) of each method (registry), then ours, per variable.

    The paper's columns follow the order of the methods in the results.
    """
    ours = results.get("lake_at_rest", {})
    paper = [METHODS[m] for m in ours if m in METHODS and "lake" in METHODS[m].paper]
    lines = ["### Seed Table 2 with our numbers", "",
             "50×50 cells, walls, T = 1 s, Voellmy (φ = 26°, ξ = 500 m/s²) and Bingham "
             "(μ = 2000 Pa s, τ_Y = 30 Pa), ρ = 1200 kg/m³. Depth error = free-surface error "
             "on wet nodes.", "",
             "| variable | "
             + "".join(f"paper {p.display} L1 | paper {p.display} L∞ | " for p in paper)
             + " | ".join(f"ours {m} L1 | ours {m} L∞" for m in ours)
             + " |", "|---|" + "---:|" * (2 * len(paper) + 2 * len(ours))]
    for var in ("h", "hu", "hv"):
        cells = [value for p in paper for value in p.paper["lake"][var]]
        for by_ranks in ours.values():
            row = next((r for r in by_ranks.get(1, []) if r["level"] == "50×50"), None)
            cells += [_fmt(row["extra"][f"{var}_l1"]) if row else "–",
                      _fmt(row["extra"][f"{var}_linf"]) if row else "–"]
        lines.append(f"| {var} | " + " | ".join(cells) + " |")
    return lines + [""]


def _hard(hard: dict[str, Rows]) -> list[str]:
    lines = ["## Hard cases for stability (`cases/hard/`, 1 rank)", "",
             "Criteria: end time reached, no NaN, h ≥ 0 after every step, "
             "|V + outflow + dried − V0| ≤ 1e-10 V0, max speed ≤ 0.9 (sqrt(2 g ΔZ) + "
             "2 sqrt(g h_max)); below a vertical "
             "drop (cliff, drop) max speed ≤ 1.1 (free fall from the release top + sqrt(g h0)); "
             "the pit must be at rest (≤ 1e-3 m/s). The same criteria run in "
             "`tests/test_hard_cases.py` (1 rank) and `tests/mpi/test_hard_cases_mpi.py` "
             "(2 and 3 ranks).", "",
             "| case | method | t reached / end | steps | wall [s] | min h | volume error | "
             "max speed / bound / free fall [m/s] | final speed | verdict |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for method, rows in hard.items():
        for r in rows:
            verdict = "pass" if not r["failures"] else "FAIL: " + "; ".join(r["failures"])
            lines.append(f"| {r['file']} | {method} | {r['t']:.3g} / {r['end']:.3g} | "
                         f"{r['steps']} | {r['wall']:.2f} | {_fmt(r['min_h'])} | "
                         f"{r['volume_error']:.1e} | {r['max_speed']:.3g} / "
                         f"{r['speed_bound']:.3g} / {r.get('fall_speed', math.nan):.3g} | "
                         f"{_fmt(r['final_speed'])} | {verdict} |")
    return lines + [""]


def _orders_text(results: dict, name: str, key: str | None, method: str) -> str:
    rows = results.get(name, {}).get(method, {}).get(1, [])
    errs = [r["error"] if key is None else r["extra"][key] for r in rows]
    return ", ".join(f"{o:.2f}" for o in orders(errs)[1:] if o is not None) or "–"


#: Errors below this are round-off (the lake at rest) and carry no rank spread.
ROUND_OFF = 1e-10


def rank_spread(results: dict, method: str) -> tuple[float, str]:
    """Largest relative difference of the error between 1 rank and any other rank count.

    Over every ladder of ``results`` (in its order, the suite's) and level that ran on more
    than one rank count, errors of round-off size (below :data:`ROUND_OFF`) left out.
    """
    worst, where = 0.0, "–"
    for bench_name, by_method in results.items():
        by_ranks = by_method.get(method, {})
        for ranks, rows in by_ranks.items():
            if int(ranks) == 1:
                continue
            for r1, rn in zip(by_ranks.get(1, []), rows, strict=False):
                if abs(r1["error"]) < ROUND_OFF:  # an error of round-off size (lake at rest)
                    continue
                diff = abs(rn["error"] - r1["error"]) / abs(r1["error"])
                if diff >= worst:
                    worst, where = diff, f"{bench_name} at {r1['level']}, {ranks} ranks"
    return worst, where


def _method_fields(results: dict, method: str) -> dict[str, Any]:
    """Return the reading's numbers of one method (serial rows), by unprefixed field name."""
    def last(name: str, key: str | None = None) -> float:
        rows = results.get(name, {}).get(method, {}).get(1, [])
        if not rows:
            return math.nan
        return rows[-1]["error"] if key is None else rows[-1]["extra"][key]

    def orders_of(name: str, key: str | None = None) -> str:
        return _orders_text(results, name, key, method)

    centre = [r["extra"]["l1_rho_0_025"] for r in
              results.get("thacker", {}).get(method, {}).get(1, [])][-2:]
    return {
        "shear_orders": orders_of("shear_decay"), "thacker_orders": orders_of("thacker"),
        "thacker2_orders": orders_of("thacker_2T"),
        "thacker_full_orders": orders_of("thacker", "full_l1"),
        "centre_band": " → ".join(f"{c:.2e}" for c in centre) or "–",
        "ritter_orders": orders_of("ritter"), "mangeney_orders": orders_of("mangeney"),
        "voellmy_last": last("voellmy_sheet"), "dam_last": last("dam_break"),
        "dam_front": last("dam_break", "front_11"),
    }


def reading(results: dict) -> str:
    """Fill :data:`READING` with this run's numbers (``–`` where a ladder is missing).

    Field names: the default method's numbers without prefix (``voellmy_last``), every other
    registered method's with its name as prefix (``mpm_voellmy_last``), and
    ``<name>_rank_spread`` for every method; fields the template does not use are ignored.
    """
    pairs = [(r1["wall"], r2["wall"]) for by_method in results.values()
             for by_ranks in by_method.values()
             for r1, r2 in zip(by_ranks.get(1, []), by_ranks.get(2, []), strict=False)]
    fields: dict[str, Any] = {"faster": sum(w2 < w1 for w1, w2 in pairs), "levels": len(pairs)}
    for method in method_names():
        prefix = "" if method == default_method() else f"{method}_"
        fields.update({prefix + k: v for k, v in _method_fields(results, method).items()})
        fields[f"{method}_rank_spread"] = _spread_text(*rank_spread(results, method))
    return READING.format(**fields)


def _spread_text(worst: float, where: str) -> str:
    return "0 (identical errors)" if worst == 0.0 else f"{worst:.1e} ({where})"


def write(benches: list[Benchmark], results: dict, hard: dict[str, Rows], out: Path,
          figures: Path, total: float) -> str:
    """Write the report and the figures; return the markdown text."""
    import dolfinx

    m = machine_info()
    stamp = f"{m['cpu']}, {m['cores']} cores, {m['date']}"
    lines = ["# Benchmarks: speed against error, both methods", "",
             f"Generated by `make bench` (`python -m fem_runout.bench suite`) on {stamp}; "
             f"{m['system']}, Python {m['python']}, DOLFINx {dolfinx.__version__}; one thread "
             f"per rank; total {total / 60:.1f} min. Methods: "
             + ", ".join(sorted({mm for r in results.values() for mm in r})) + ". Wall time = "
             "time loop only (no set-up, no output); errors are from the 1-rank run (the "
             "2-rank run gives the same numbers to round-off).", ""]
    for bench in benches:
        by_method = results.get(bench.name, {})
        lines += [f"## {bench.title}", "", REFERENCES[bench.reference], "",
                  f"Error: {bench.norm}.", ""]
        for method, by_ranks in by_method.items():
            lines += [f"**{method}**", "", *ladder_table(bench, by_ranks), ""]
        fig = figures / f"bench_{bench.name}.png"
        if plot(bench, by_method, fig, stamp):
            rel = Path("figures") / fig.name if out.parent == figures.parent else fig
            lines += [f"![{bench.name}]({rel.as_posix()})", ""]
        else:
            lines += ["(no figure: every error is exactly 0)", ""]
        if bench.name == "dam_break":
            lines += _table1(results)
        if bench.name == "lake_at_rest":
            lines += _table2(results)
    if hard:
        lines += _hard(hard)
    lines += [reading(results), ""]
    text = "\n".join(lines)
    out.parent.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    raw = {"machine": m, "total_seconds": total, "ladders": results, "hard": hard}
    (figures / "bench_results.json").write_text(json.dumps(raw, indent=1))
    return text
