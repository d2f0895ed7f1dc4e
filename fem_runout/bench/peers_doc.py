"""docs/peers.md from the side-by-side runs (:mod:`fem_runout.bench.side_by_side`).

Every number is a median over the alternating rounds; ratios are ratios of medians of runs
made in the same session, on the same machine, one core each.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.bench.peers_ladder import ladder_lines
from fem_runout.bench.step_cost import machine_info

__all__ = ["avakot_table", "dam_table", "median_row", "write_doc"]

PEERS = {"dam": "GeoClaw", "avakot": "com1DFA"}


def median_row(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Median of every numeric entry over the rounds, plus ``wall_min``/``wall_max``."""
    row: dict[str, Any] = {}
    for key, value in runs[0].items():
        values = [r[key] for r in runs]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            row[key] = float(np.median(values))
        else:
            row[key] = value
    walls = [r["wall"] for r in runs]
    row.update(wall_min=min(walls), wall_max=max(walls), rounds=len(runs))
    return row


def _wall(row: dict[str, Any]) -> str:
    return f"{row['wall']:.2f} ({row['wall_min']:.2f}–{row['wall_max']:.2f})"


def dam_table(rows: dict[str, dict[str, Any]], grid: tuple[int, int]) -> list[str]:
    """Markdown rows of the dam-break table; ratios against GeoClaw's medians."""
    ref = rows.get("GeoClaw")
    lines = ["| code | steps | loop wall [s], median (range) | µs per cell-step | front at 11 s "
             "[m] | error vs exact tip | wall ÷ GeoClaw | steps ÷ GeoClaw | wall per step ÷ "
             "GeoClaw |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in rows.items():
        us = 1e6 * r["wall"] / (grid[0] * grid[1] * r["steps"])
        ratios = ["", "", ""]
        if ref is not None:
            ratios = [f"{r['wall'] / ref['wall']:.2f}", f"{r['steps'] / ref['steps']:.2f}",
                      f"{(r['wall'] / r['steps']) / (ref['wall'] / ref['steps']):.2f}"]
        lines.append(f"| {name} | {r['steps']:.0f} | {_wall(r)} | {us:.2f} | {r['front']:.1f} | "
                     f"{r['error']:.3f} | " + " | ".join(ratios) + " |")
    return lines


def avakot_table(rows: dict[str, dict[str, Any]]) -> list[str]:
    """Markdown rows of the avaKot table; ratios against com1DFA at the same cell size."""
    lines = ["| model | cell [m] | released [m³] | particles (end) | steps | loop wall [s], "
             "median (range) | µs per cell- or particle-step | run-out ≥ 1 cm [m] | area ≥ 1 cm "
             "[ha] | area ≥ 0.1 m [ha] | peak thickness [m] | peak speed [m/s] | wall ÷ com1DFA "
             "(same cell) | wall ÷ com1DFA (its default 5 m) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    peers = {r["cell"]: r for name, r in rows.items() if name.startswith("com1DFA")}
    for name, r in rows.items():
        ratio = " | ".join(f"{r['wall'] / ref['wall']:.2f}" if ref is not None else ""
                           for ref in (peers.get(r["cell"]), peers.get(5.0)))
        particles = f"{r['particles']:.0f}" if r.get("particles") else ""
        lines.append(
            f"| {name} | {r['cell']:g} | {r['released_volume']:.0f} | {particles} | "
            f"{r['steps']:.0f} | {_wall(r)} | {1e6 * r['wall'] / r['work']:.2f} | "
            f"{r['runout_0.01']:.0f} | {r['area_0.01'] / 1e4:.1f} | {r['area_0.1'] / 1e4:.1f} | "
            f"{r['peak_depth']:.2f} | {r['peak_speed']:.1f} | {ratio} |")
    return lines


def _git_rev(root: Path) -> str:
    res = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty",
                          "--abbrev=7"],
                         capture_output=True, text=True, check=False)
    return res.stdout.strip() or "unknown"


def _header(by_scene: dict[str, dict[str, dict[str, Any]]], options: dict[str, Any],
            root: Path) -> list[str]:
    m = machine_info()
    versions = sorted({r["version"] for rows in by_scene.values() for r in rows.values()
                       if r.get("version")})
    rounds = max((r["rounds"] for rows in by_scene.values() for r in rows.values()), default=0)
    return [
        "# Peer models side by side", "",
        "Written by `make bench-peers` (`python -m fem_runout.bench side-by-side`; "
        "`fem_runout/bench/side_by_side.py` says how each number is measured). "
        f"Measured {m['date']} on {m['cpu']} ({m['cores']} cores), one core per code, fem_runout "
        f"{_git_rev(root)}, {', '.join(versions)}. Every code ran {rounds} times, alternating "
        "(peer, TG2-PC, DAMPM, peer, …); the numbers are medians, the range is over the rounds.",
        "", "The peers live in their own virtualenvs outside the project "
        "(`peers/README.md`); they are never dependencies of fem_runout.", ""]


def _ladder_section(runs: dict[str, list[dict[str, Any]]], options: dict[str, Any]) -> list[str]:
    """Return the dam break's ladder section (:mod:`fem_runout.bench.peers_ladder`), if run."""
    from fem_runout import methods

    ours = methods.get(options.get("ladder_method") or methods.default_method()).display
    table = ladder_lines(runs, ours)
    if not table:
        return []
    figure = Path(options.get("figure", "figures/peers_avakot.png"))
    return ["### Cost at equal accuracy: a resolution ladder for both", "",
            f"GeoClaw and {ours} on the side-by-side grid times "
            f"{', '.join(f'{f:g}' for f in options.get('ladder', ()))} (cells in the same "
            "aspect), one run per level beside the rounds' medians on the side-by-side grid. "
            "Wall times at the other code's error: `log wall` interpolated linearly in "
            "`log error` between the two levels that bracket it "
            "(`fem_runout/bench/peers_ladder.py`).", "", *table, "",
            f"![wall time against front error](figures/"
            f"{figure.with_name('peers_dam_ladder.png').name})", ""]


def write_doc(out: Path, runs: dict[str, list[dict[str, Any]]], options: dict[str, Any]) -> None:
    """Write ``out`` (markdown) and the raw runs next to it (``.json``).

    Args:
        out: The markdown file.
        runs: ``"scene:name"`` -> the numbers of each round (``scene``: dam or avakot).
        options: The command's options (``grid``, ``figure``).
    """
    by_scene: dict[str, dict[str, dict[str, Any]]] = {}
    for key, rounds in runs.items():
        scene, _, name = key.partition(":")
        if rounds:
            by_scene.setdefault(scene, {})[name] = median_row(rounds)
    root = Path(__file__).resolve().parents[2]
    lines = _header(by_scene, options, root)
    if "dam" in by_scene:
        nx, ny = options["grid"]
        lines += [f"## Inclined dam break against GeoClaw ({nx} × {ny} cells)", "",
                  "`cases/inclined_dam_break_450.yaml`: [0, 450] × [0, 20] m, bed 100 − x/3, "
                  "frictionless, 11 s, CFL 0.9 for all. GeoClaw: one grid level (no AMR), "
                  "second order with MC limiter and transverse waves, dry tolerance 1e-6 m, wall = "
                  "the `xgeoclaw` process (two output frames). Ours: the time loop with outputs "
                  "at 5.5 and 11 s. Front = largest x with h > 1e-3 m (GeoClaw: cell centres, "
                  "mean over the rows; ours: nodes).", ""]
        lines += dam_table(by_scene["dam"], (nx, ny)) + [""]
        lines += _ladder_section(runs, options)
    if "avakot" in by_scene:
        lines += ["## avaKot against com1DFA", "",
                  "Same DEM, release polygon (1 m normal to the slope), Voellmy μ = 0.155, "
                  "ξ = 4000 m/s², ρ = 200 kg/m³, stop when the kinetic energy falls below 1e-4 of "
                  "its peak. Maps, areas and run-outs from each code's rasters with one "
                  "definition (`fem_runout.bench.peers.raster_metrics`): slope-normal peak "
                  "thickness, run-out from the release's highest pixel. Work = cell-steps for "
                  "TG2-PC (whole mesh), particle-steps (final count) for the particle codes.", ""]
        lines += avakot_table(by_scene["avakot"])
        figure = Path(options.get("figure", "figures/peers_avakot.png"))
        lines += ["", f"![slope-normal peak thickness, side by side](figures/{figure.name})", ""]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps(runs, indent=1, default=str) + "\n")
