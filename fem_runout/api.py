"""Python API: ``load_case`` and ``run`` (collective), the same code path as the CLI."""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fem_runout.config import Case, dump_resolved, load_case
from fem_runout.errors import CaseError

IMPLEMENTED_METHODS = frozenset({"tg2", "mpm"})

__all__ = ["IMPLEMENTED_METHODS", "RunResult", "load_case", "run"]


@dataclass
class RunResult:
    """What a run returns; the arrays are set on rank 0 only (None elsewhere).

    Node arrays share one global order, sorted by (y, x), independent of the rank count.

    Attributes:
        x, y: Node coordinates [m].
        h, hu, hv, z: Final depth, momenta and elevation.
        peak_depth, peak_speed: Maximum over the run of depth and speed per node.
        series: Time series (column name -> array), see ``series.csv``.
        wall_time: Seconds spent in the time loop.
        steps: Number of time steps.
        t: Final time.
        out_dir: Output folder (None when nothing was written).
        particles: Final number of particles (DAMPM; None for mesh-only methods).
        at_rest: The run stopped because the flow came to rest (``time.end: auto``).
        summary: Released, deposit and outflow volumes, peaks, affected area, run-out length
            (see ``summary.json``; the same on every rank).
    """

    x: np.ndarray | None = None
    y: np.ndarray | None = None
    h: np.ndarray | None = None
    hu: np.ndarray | None = None
    hv: np.ndarray | None = None
    z: np.ndarray | None = None
    peak_depth: np.ndarray | None = None
    peak_speed: np.ndarray | None = None
    series: dict[str, np.ndarray] = field(default_factory=dict)
    wall_time: float = 0.0
    steps: int = 0
    t: float = 0.0
    out_dir: Path | None = None
    particles: int | None = None
    at_rest: bool = False
    summary: dict = field(default_factory=dict)


class _Progress:
    """tqdm bar on rank 0: simulated time, dt, step, ETA."""

    def __init__(self, end: float, name: str) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=end, desc=name, unit="s", file=sys.stderr, mininterval=1.0,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t={n:.3g}/{total:.3g} s "
                        "[{elapsed}<{remaining}{postfix}]")
        self.t = 0.0

    def update(self, info) -> None:
        self.bar.update(info.t - self.t)
        self.t = info.t
        self.bar.set_postfix_str(f"dt={info.dt:.2e} step={info.step}", refresh=False)

    def close(self) -> None:
        self.bar.close()


def _prepare_out_dir(case: Case, comm, overwrite: bool) -> Path:
    out = case.output_dir
    bad = None
    if comm.rank == 0 and out.exists() and any(out.iterdir()):
        if overwrite:
            shutil.rmtree(out)
        else:
            bad = f"output dir '{out}' is not empty; pass --overwrite to replace it"
    bad = comm.bcast(bad, root=0)
    if bad:
        raise CaseError(bad)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        (out / "case.resolved.yaml").write_text(dump_resolved(case))
    comm.barrier()
    return out


def build_solver(case: Case, comm):
    """Build the solver of ``case.method`` (collective)."""
    if case.method not in IMPLEMENTED_METHODS:
        raise CaseError(
            f"method: '{case.method}' is not implemented yet; available: "
            + ", ".join(sorted(IMPLEMENTED_METHODS))
        )
    if case.method == "mpm":
        from mpm.build import build_mpm

        return build_mpm(case, comm)
    from fem_runout.tg2.solver import build_tg2

    return build_tg2(case, comm)


def run(
    case: Case | str | Path | dict,
    *,
    overwrite: bool = False,
    quiet: bool = True,
    write: bool = True,
    comm=None,
) -> RunResult:
    """Run a case (collective on ``comm``, default COMM_WORLD).

    Args:
        case: A validated case, or a path/mapping given to :func:`load_case`.
        overwrite: Replace a non-empty output folder.
        quiet: No progress bar and no summary.
        write: Write the output folder (fields, series, peaks, pictures).
        comm: MPI communicator.

    Returns:
        The final state and diagnostics (arrays on rank 0).
    """
    from mpi4py import MPI

    from fem_runout.output import FieldWriter, PeakTracker, Pictures, SeriesRecorder, gather_nodal
    from fem_runout.output.hazard import HazardMaps
    from fem_runout.runner import Runner, Schedule

    comm = comm or MPI.COMM_WORLD
    if not isinstance(case, Case):
        case = load_case(case)
    elif case.terrain.dem is not None and case.domain.extent is None:
        from fem_runout.terrain.resolve import resolve_terrain

        case = resolve_terrain(case)  # a Case built without load_case
    solver = build_solver(case, comm)
    out = _prepare_out_dir(case, comm, overwrite) if write else None
    thr = case.output.front_threshold
    recorder = SeriesRecorder((out or Path(".")) / "series.csv", thr, case.material.density)
    if out is None:
        recorder.write_csv = lambda: None  # type: ignore[method-assign]
    peaks = PeakTracker(out, thr)
    callbacks = [recorder, peaks]
    if out is not None:
        callbacks.insert(
            0, FieldWriter(out, solver, threshold=case.numerics.dry_tolerance, pvd=case.output.vtk)
        )
        if case.output.pictures:
            callbacks.append(Pictures(out, case.name, recorder, peaks, threshold=thr))
        if hasattr(solver, "particles"):
            from mpm.output import ParticleWriter

            callbacks.append(ParticleWriter(out))
    hazard = HazardMaps(case, out if case.output.hazard else None, case.output.pictures)
    callbacks.append(hazard)
    t = case.time
    schedule = Schedule(t.end_time, t.cfl, case.output.every, t.max_steps, t.dt_max,
                        t.rest_speed if t.auto else None, t.rest_duration, thr, t.rest_energy)
    if not quiet:
        _say_released(solver, comm)
    progress = _Progress(t.end_time, case.name) if (not quiet and comm.rank == 0) else None
    runner = Runner(solver, schedule, callbacks, progress)
    info = runner.run()
    final = gather_nodal(solver.V, {k: f.x.array for k, f in solver.fields.items()})
    envelope = peaks.gathered()
    result = RunResult(series=recorder.series, wall_time=runner.wall_time, steps=info.step,
                       t=info.t, out_dir=out, at_rest=runner.at_rest,
                       particles=getattr(solver, "n_particles", None))
    result.summary = {**hazard.summary, "t_end": info.t, "steps": info.step,
                      "at_rest": runner.at_rest, "wall_time": runner.wall_time,
                      "ranks": comm.size, "method": case.method,
                      "particles": result.particles}
    if out is not None and comm.rank == 0:
        (out / "summary.json").write_text(json.dumps(result.summary, indent=2) + "\n")
    if final is not None:
        for key in ("x", "y", "h", "hu", "hv", "z"):
            setattr(result, key, final[key])
        result.peak_depth, result.peak_speed = envelope["peak_depth"], envelope["peak_speed"]
    if not quiet and comm.rank == 0:
        _summary(result, comm.size)
    return result


def _say_released(solver, comm) -> None:
    """Print the released volume ``Σ M_i h_i`` on rank 0 (collective)."""
    from fem_runout.output import global_sum

    n = solver.V.dofmap.index_map.size_local
    volume = global_sum(comm, solver.lumped_mass[:n] @ solver.fields["h"].x.array[:n])
    if comm.rank == 0:
        print(f"released volume: {volume:.6g} m³", flush=True)


def _summary(result: RunResult, ranks: int) -> None:
    err = result.series.get("mass_error", np.array([np.nan]))
    rest = " (flow at rest)" if result.at_rest else ""
    print(
        f"done: {result.steps} steps to t = {result.t:.4g} s{rest} in "
        f"{result.wall_time:.2f} s wall "
        f"on {ranks} rank(s); relative mass error {float(err[-1]):.2e}"
        + (f"; results in {result.out_dir}/" if result.out_dir else ""),
        flush=True,
    )
