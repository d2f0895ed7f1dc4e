r"""Wall time against front error: the inclined dam break's resolution ladder, ours and GeoClaw's.

The same-grid table of docs/peers.md compares work per cell; users compare what an answer of
a given accuracy costs. Both codes therefore run the dam break on a ladder of grids (the
side-by-side grid times ``--ladder`` factors, cells kept in the same aspect), and each code's
wall time is read **at the other's front error**: between two levels, ``log wall`` is
interpolated linearly in ``log error`` (the two levels bracketing the error). Outside a code's
ladder nothing is extrapolated: an error below its finest level's costs more than that level
(``> wall``), one above its coarsest level's less than that level (``< wall``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ladder_grids", "ladder_lines", "ladder_figure", "wall_at_error"]


def ladder_grids(grid: tuple[int, int], factors: tuple[float, ...]) -> list[tuple[int, int]]:
    """Grids ``(round(f nx), max(2, round(f ny)))`` of the ladder, coarse to fine, unique."""
    out = sorted({(max(2, round(f * grid[0])), max(2, round(f * grid[1]))) for f in factors})
    return out


def wall_at_error(errors: list[float], walls: list[float], error: float
                  ) -> tuple[float, str]:
    """Wall time of a ladder at ``error``, or a bound on it where the ladder does not reach.

    Args:
        errors: The ladder's front errors (any order; at least two levels).
        walls: Its wall times, one per level.
        error: The error at which to read the wall time.

    Returns:
        ``(wall, "")``: ``log wall`` linear in ``log error`` between the two levels (adjacent
        in cost) whose errors bracket ``error``. ``(finest wall, ">")`` if ``error`` is below
        every level's error: a more accurate answer costs at least the finest level's time
        (no extrapolation). ``(cheapest wall, "<")`` if it is above every level's error.
    """
    e, w = np.log(np.asarray(errors, float)), np.log(np.asarray(walls, float))
    order = np.argsort(w)  # cheapest first: the natural reading of a ladder
    e, w, x = e[order], w[order], np.log(error)
    for a in range(e.size - 1):
        b = a + 1
        if min(e[a], e[b]) <= x <= max(e[a], e[b]) and e[a] != e[b]:
            return float(np.exp(w[a] + (w[b] - w[a]) * (x - e[a]) / (e[b] - e[a]))), ""
    if x < e.min():
        return float(np.exp(w[np.argmin(e)])), ">"
    return float(np.exp(w[np.argmax(e)])), "<"


def _rows(runs: dict[str, list[dict[str, Any]]], code: str) -> list[dict[str, Any]]:
    """Return one code's ladder levels, coarse to fine (medians if run more than once)."""
    rows = []
    for key, levels in runs.items():
        scene, _, name = key.partition(":")
        if scene == "ladder" and name.rsplit(" ", 1)[0] == code and levels:
            row = {k: float(np.median([r[k] for r in levels]))
                   for k in ("wall", "steps", "error", "nx", "ny")}
            rows.append(row)
    return sorted(rows, key=lambda r: r["nx"])


def ladder_lines(runs: dict[str, list[dict[str, Any]]], ours: str = "TG2-PC",
                 peer: str = "GeoClaw") -> list[str]:
    """Markdown: both ladders, then each level's wall against the other code's at equal error."""
    mine, theirs = _rows(runs, ours), _rows(runs, peer)
    if len(mine) < 2 or len(theirs) < 2:
        return []
    lines = ["| code | cells | steps | loop wall [s] | front error at 11 s |",
             "|---|---:|---:|---:|---:|"]
    for code, rows in ((peer, theirs), (ours, mine)):
        lines += [f"| {code} | {r['nx']:.0f} × {r['ny']:.0f} | {r['steps']:.0f} | "
                  f"{r['wall']:.2f} | {r['error']:.4f} |" for r in rows]
    lines += ["", f"At equal front error ({peer}'s wall read off its ladder at each {ours} "
              "level's error, and the other way round; `>`/`<`: beyond the ladder, a bound):",
              "",
              f"| level | front error | {ours} wall [s] | {peer} wall [s] at that error | "
              f"{ours} ÷ {peer} |", "|---|---:|---:|---:|---:|"]
    for code, rows, other in ((ours, mine, theirs), (peer, theirs, mine)):
        for r in rows:
            wall, bound = wall_at_error([o["error"] for o in other],
                                        [o["wall"] for o in other], r["error"])
            mine_wall, peer_wall = (r["wall"], wall) if code == ours else (wall, r["wall"])
            # a bound on the other code's wall bounds the ratio the other way for the peer
            flip = {">": "<", "<": ">", "": ""}
            ratio_bound = bound if code != ours else flip[bound]
            cell = f"{bound} {wall:.2f}".strip()
            lines.append(f"| {code} {r['nx']:.0f} × {r['ny']:.0f} | {r['error']:.4f} | "
                         + (f"{mine_wall:.2f} | {cell} |" if code == ours
                            else f"{cell} | {peer_wall:.2f} |")
                         + f" {ratio_bound} {mine_wall / peer_wall:.3f} |".replace("  ", " "))
    return lines


def ladder_figure(runs: dict[str, list[dict[str, Any]]], path: Path,
                  codes: tuple[str, ...] = ("GeoClaw", "TG2-PC")) -> bool:
    """Plot wall time against front error for each code's ladder; False if there is none."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = {c: _rows(runs, c) for c in codes}
    if not all(len(rows) >= 2 for rows in data.values()):
        return False
    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    for code, rows in data.items():
        ax.loglog([r["error"] for r in rows], [r["wall"] for r in rows], "o-", label=code)
        for r in rows:
            ax.annotate(f"{r['nx']:.0f}", (r["error"], r["wall"]), fontsize=7,
                        textcoords="offset points", xytext=(4, 4))
    ax.set_xlabel("front error at 11 s (relative to the exact tip)")
    ax.set_ylabel("loop wall time [s], one core")
    ax.set_title("Inclined dam break: cost against accuracy")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True
