r"""Run the peer models and both methods alternately on the same inputs; write docs/peers.md.

``make bench-peers`` installs the peers (``peers/geoclaw/setup.sh``, ``peers/com1dfa/setup.sh``:
their own virtualenvs outside the project) and then runs::

    python -m fem_runout.bench side-by-side --rounds 3 --out docs/peers.md

Two scenes, one core each, every code run once per round in a fixed order (GeoClaw, TG2-PC,
DAMPM, TG2-PC with the positivity step bound; com1DFA, the same), so a slow spell of the
machine hits every code alike; the tables give the median and the range over the rounds. The
positivity rows are TG2-PC with ``numerics.step_bound: positivity`` (the depth's own step
bound, about half the steps of a fast flow; docs/method.md):

- the inclined dam break on [0, 450] × [0, 20] m (``cases/inclined_dam_break_450.yaml``) on
  the same grid for all (GeoClaw: cells, one level, no AMR; ours: Q1 nodes on the same
  cells), front error at 11 s against the exact dry-bed tip;
- avaKot (``cases/avakot.yaml``, same DEM, release, Voellmy parameters and rest criterion)
  against com1DFA at our cell size and at its default 5 m; every map number is computed from
  the rasters by :func:`fem_runout.bench.peers.raster_metrics`, so the definitions agree.

Wall times are the time loops (ours: the runner's loop with its outputs; GeoClaw: the
``xgeoclaw`` process; com1DFA: its ``timeLoop``). Our runs share one process: one short
warm-up run per method loads the compiled kernels before the rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.bench.peers import depth_maps_figure, our_metrics, peer_metrics
from fem_runout.bench.peers_doc import write_doc
from fem_runout.bench.peers_ladder import ladder_figure, ladder_grids
from fem_runout.methods import default_method, get, method_names

__all__ = ["HELP", "Job", "add_arguments", "main", "peer_pythons"]

HELP = "run GeoClaw and com1DFA alternately with both methods on the same inputs (docs/peers.md)"
ROOT = Path(__file__).resolve().parents[2]
CASES = ROOT / "cases"
PEERS_HOME = Path.home() / ".cache" / "fem_runout" / "peers"
METHODS = tuple(method_names())
#: Methods with a choice of time-step bound: each gets a second row with the depth's own bound.
_STEP_BOUNDS = tuple(m for m in METHODS if get(m).step_bounds)
POSITIVITY = ("numerics.step_bound=positivity",)


@dataclass(frozen=True)
class Job:
    """One code on one scene.

    Attributes:
        scene: ``"dam"`` or ``"avakot"``.
        name: Row label (also the work sub-folder).
        run: Runs once in the given folder and returns its numbers (``wall``, ``steps``,
            ``work`` (cell- or particle-steps) and the scene's accuracy numbers), plus the
            peak-thickness raster and transform for avaKot (``None`` for the dam break).
    """

    scene: str
    name: str
    run: Callable[[Path], tuple[dict[str, Any], Any]]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options."""
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/fem_runout_peers"),
                        help="work folder for every run's files (outside the repository)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "peers.md")
    parser.add_argument("--figure", type=Path, default=ROOT / "docs" / "figures" /
                        "peers_avakot.png")
    parser.add_argument("--geoclaw-venv", type=Path, default=PEERS_HOME / "geoclaw")
    parser.add_argument("--avaframe-venv", type=Path, default=PEERS_HOME / "avaframe")
    parser.add_argument("--grid", type=int, nargs=2, default=(495, 33), metavar=("NX", "NY"),
                        help="dam-break cells (default 495 33: dx = 0.91 m)")
    parser.add_argument("--ladder", type=float, nargs="+", default=(0.25, 0.5, 1.0, 2.0),
                        metavar="F", help="dam-break ladder: --grid times these factors, run "
                        "once each by GeoClaw and TG2-PC after the rounds (default 0.25 0.5 1 "
                        "2; `--ladder 1` for none)")
    parser.add_argument("--ladder-method", choices=METHODS, default=default_method(),
                        help="our method on the ladder (default: the default method)")
    parser.add_argument("--com1dfa-cells", type=float, nargs="+", default=(10.0, 5.0),
                        help="com1DFA mesh cell sizes (default: ours, 10 m, and its default 5 m)")
    parser.add_argument("--skip", choices=("dam", "avakot"), action="append", default=[],
                        help="leave a scene out")
    parser.add_argument("--replay", type=Path, metavar="JSON",
                        help="only rewrite the doc from an earlier run's .json (no runs)")


def peer_pythons(args: argparse.Namespace) -> dict[str, Path]:
    """Return the peers' interpreters; :class:`FileNotFoundError` says how to install one."""
    need = {"geoclaw": (args.geoclaw_venv, "peers/geoclaw/setup.sh", "dam"),
            "avaframe": (args.avaframe_venv, "peers/com1dfa/setup.sh", "avakot")}
    found = {}
    for name, (venv, script, scene) in need.items():
        if scene in args.skip:
            continue
        python = venv / "bin" / "python"
        if not python.is_file():
            raise FileNotFoundError(f"{name}: no virtualenv at {venv}; install it with "
                                    f"`bash {script}` (or `make bench-peers`)")
        found[name] = python
    return found


def _claw_env(venv: Path) -> dict[str, str]:
    """Environment with GeoClaw's ``CLAW`` and ``FC`` from the venv's ``geoclaw.env``."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for line in (venv / "geoclaw.env").read_text().splitlines():
        key, sep, value = line.removeprefix("export ").partition("=")
        if sep:
            env[key.strip()] = value.strip().strip('"')
    return env


def _subprocess(cmd: list[str], env: dict[str, str] | None, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    (folder / "command.log").write_text(" ".join(cmd) + "\n" + res.stdout + res.stderr)
    if res.returncode != 0:
        raise RuntimeError(f"{cmd[1]} failed ({res.returncode}); see {folder / 'command.log'}")


def _geoclaw(args: argparse.Namespace, python: Path, grid: tuple[int, int] | None = None,
             scene: str = "dam") -> Job:
    nx, ny = grid or args.grid

    def run(folder: Path) -> tuple[dict[str, Any], None]:
        _subprocess([str(python), str(ROOT / "peers/geoclaw/run_dam_break.py"), "--nx", str(nx),
                     "--ny", str(ny), "--xmax", "450", "--out", str(folder)],
                    _claw_env(args.geoclaw_venv), folder)
        s = json.loads((folder / "summary.json").read_text())
        return {"wall": s["wall_time"], "steps": s["steps"], "work": nx * ny * s["steps"],
                "front": s["front_11"], "error": s["rel_11"], "nx": nx, "ny": ny,
                "version": f"clawpack {s['clawpack_version']}"}, None

    return Job(scene, "GeoClaw" if scene == "dam" else f"GeoClaw {nx}x{ny}", run)


def _our_dam(method: str, grid: tuple[int, int], scene: str = "dam",
             extra: tuple[str, ...] = ()) -> Job:
    from fem_runout.references.inclined_dam_break import exact_front

    def run(folder: Path) -> tuple[dict[str, Any], None]:
        r = _run_case("inclined_dam_break_450", method, f"domain.cells=[{grid[0]},{grid[1]}]",
                      "output.every=5.5", *extra)
        front = float(r.series["front_x"][int(np.argmin(np.abs(r.series["t"] - 11.0)))])
        work = (r.particles if r.particles else grid[0] * grid[1]) * r.steps
        return {"wall": r.wall_time, "steps": r.steps, "work": work, "front": front,
                "error": abs(front / exact_front(11.0) - 1.0), "particles": r.particles,
                "nx": grid[0], "ny": grid[1]}, None

    label = _label(method, extra)
    return Job(scene, label if scene == "dam" else f"{label} {grid[0]}x{grid[1]}", run)


def _com1dfa(args: argparse.Namespace, python: Path, cell: float) -> Job:
    def run(folder: Path) -> tuple[dict[str, Any], Any]:
        out = folder / "out"
        _subprocess([str(python), str(ROOT / "peers/com1dfa/run_avakot.py"), "--out", str(out),
                     "--work", str(folder), "--no-report",
                     "--set", f"GENERAL.meshCellSize={cell:g}"], None, folder)
        metrics, depth, transform = peer_metrics(out)
        s = json.loads((out / "summary.json").read_text())
        particles, steps = int(s["n_particles_final"]), int(s["n_iterations"])
        metrics.update(wall=float(s["wall_time_time_loop_s"]), steps=steps, cell=cell,
                       particles=particles, work=particles * steps,
                       version=f"AvaFrame {s['avaframe_version']}")
        return metrics, (depth, transform)

    return Job("avakot", f"com1DFA {cell:g} m", run)


def _our_avakot(method: str, extra: tuple[str, ...] = ()) -> Job:
    def run(folder: Path) -> tuple[dict[str, Any], Any]:
        r = _run_case("avakot", method, f"output.dir={folder}", "output.pictures=false",
                      *extra, write=True)
        metrics, depth, transform = our_metrics(folder)
        work = (r.particles if r.particles else _mesh_cells(r)) * r.steps
        metrics.update(wall=r.wall_time, steps=r.steps, cell=10.0, particles=r.particles,
                       work=work)
        return metrics, (depth, transform)

    return Job("avakot", _label(method, extra), run)


def _mesh_cells(result: Any) -> int:
    """Cells of a structured run from its node count (nodes = (nx + 1)(ny + 1))."""
    nx = len(np.unique(result.x)) - 1
    return nx * (len(result.x) // (nx + 1) - 1)


def _label(method: str, extra: tuple[str, ...] = ()) -> str:
    from fem_runout import methods

    return methods.get(method).display + (" (positivity step)" if POSITIVITY == extra else "")


def _run_case(name: str, method: str, *overrides: str, write: bool = False) -> Any:
    from mpi4py import MPI

    from fem_runout.api import run
    from fem_runout.config import load_case

    case = load_case(CASES / f"{name}.yaml", [f"method={method}", *overrides])
    return run(case, write=write, overwrite=True, comm=MPI.COMM_SELF)


def build_jobs(args: argparse.Namespace, pythons: dict[str, Path]) -> list[Job]:
    """Return the jobs of one round, in their fixed order."""
    jobs: list[Job] = []
    if "dam" not in args.skip:
        jobs += [_geoclaw(args, pythons["geoclaw"])]
        jobs += [_our_dam(m, tuple(args.grid)) for m in METHODS]
        jobs += [_our_dam(m, tuple(args.grid), extra=POSITIVITY) for m in _STEP_BOUNDS]
    if "avakot" not in args.skip:
        jobs += [_com1dfa(args, pythons["avaframe"], c) for c in args.com1dfa_cells]
        jobs += [_our_avakot(m) for m in METHODS]
        jobs += [_our_avakot(m, POSITIVITY) for m in _STEP_BOUNDS]
    return jobs


def ladder_jobs(args: argparse.Namespace, pythons: dict[str, Path]) -> list[Job]:
    """Return the dam-break ladder's jobs off ``--grid`` (GeoClaw, then ours, per level)."""
    if "dam" in args.skip:
        return []
    jobs: list[Job] = []
    for grid in ladder_grids(tuple(args.grid), tuple(args.ladder)):
        if grid != tuple(args.grid):
            jobs += [_geoclaw(args, pythons["geoclaw"], grid, "ladder"),
                     _our_dam(args.ladder_method, grid, "ladder")]
    return jobs


def _ladder_runs(runs: dict[str, list[dict[str, Any]]], args: argparse.Namespace) -> None:
    """Add the rounds' ``--grid`` runs to the ladder (in place) if the ladder was run."""
    if not any(key.startswith("ladder:") for key in runs):
        return
    nx, ny = args.grid
    for name in ("GeoClaw", _label(args.ladder_method)):
        runs[f"ladder:{name} {nx}x{ny}"] = runs.get(f"dam:{name}", [])


def _run_job(job: Job, args: argparse.Namespace, runs: dict[str, list[dict[str, Any]]],
             maps: dict[str, Any], label: str) -> None:
    """Run one job, record its numbers (and map), print a line."""
    metrics, depth_map = job.run(args.work / job.scene / job.name.replace(" ", "_"))
    runs.setdefault(f"{job.scene}:{job.name}", []).append(metrics)
    if depth_map is not None:
        maps[job.name] = depth_map
    print(f"{label} {job.scene:6s} {job.name:14s} wall {metrics['wall']:7.2f} s, "
          f"{metrics['steps']} steps", flush=True)


def _warm_up() -> None:
    """Load every method's compiled kernels once (short dam break, nothing written)."""
    for method in METHODS:
        _run_case("inclined_dam_break_450", method, "domain.cells=[99,7]", "time.end=0.5")


def main(args: argparse.Namespace) -> int:
    """Run the rounds, print each run, write the doc, its JSON and the maps' figure."""
    if args.replay is not None:
        write_doc(args.out, json.loads(args.replay.read_text()), vars(args))
        return 0
    try:
        pythons = peer_pythons(args)
    except FileNotFoundError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    jobs = build_jobs(args, pythons)
    _warm_up()
    runs: dict[str, list[dict[str, Any]]] = {f"{job.scene}:{job.name}": [] for job in jobs}
    maps: dict[str, Any] = {}
    for k in range(args.rounds):
        for job in jobs:
            _run_job(job, args, runs, maps, f"round {k + 1}/{args.rounds}")
    for job in ladder_jobs(args, pythons):
        _run_job(job, args, runs, maps, "ladder")
    _ladder_runs(runs, args)
    write_doc(args.out, runs, vars(args))
    if maps:
        depth_maps_figure(maps, args.figure)
    ladder_figure(runs, args.figure.with_name("peers_dam_ladder.png"),
                  ("GeoClaw", _label(args.ladder_method)))
    print(f"wrote {args.out}")
    return 0
