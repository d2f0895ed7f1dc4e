"""Python API: ``load_case`` and ``run`` (collective), the same code path as the CLI."""

from __future__ import annotations

import json
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fem_runout import methods
from fem_runout.config import Case, dump_resolved, load_case
from fem_runout.errors import CaseError, RunInterrupted, SimulationError

if TYPE_CHECKING:
    from fem_runout.callbacks import Callback
    from fem_runout.solver_api import Solver

__all__ = ["RunResult", "build_solver", "load_case", "run"]


@dataclass
class RunResult:
    """What a run returns; the arrays are set on rank 0 only (None elsewhere).

    Node arrays share one global order, sorted by (y, x), independent of the rank count.

    Attributes:
        x, y: Node coordinates [m].
        h, hu, hv, z: Final depth, momenta and elevation.
        peak_depth, peak_speed: Maximum over the run of depth and speed per node.
        area: Nodal area ``∫ φ_i`` (the lumped Q1 mass): the weights of nodal integrals.
        cells: Number of cells of the mesh (every rank).
        series: Time series (column name -> array), see ``series.csv``.
        wall_time: Seconds spent in the time loop.
        steps: Number of time steps.
        t: Final time.
        out_dir: Output folder (None when nothing was written).
        particles: Final number of particles (DAMPM; None for mesh-only methods).
        at_rest: The run stopped because the flow came to rest (``time.end: auto``).
        summary: Released, deposit and outflow volumes, peaks, affected area, run-out length
            (see ``summary.json``; the same on every rank).
        error: Why the run stopped early (NaN, negative depth), with ``raise_errors=False``;
            the fields are then the last good state. None for a complete run.
    """

    x: np.ndarray | None = None
    y: np.ndarray | None = None
    h: np.ndarray | None = None
    hu: np.ndarray | None = None
    hv: np.ndarray | None = None
    z: np.ndarray | None = None
    peak_depth: np.ndarray | None = None
    peak_speed: np.ndarray | None = None
    area: np.ndarray | None = None
    cells: int = 0
    series: dict[str, np.ndarray] = field(default_factory=dict)
    wall_time: float = 0.0
    steps: int = 0
    t: float = 0.0
    out_dir: Path | None = None
    particles: int | None = None
    at_rest: bool = False
    summary: dict = field(default_factory=dict)
    error: str | None = None


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


def _checkpoint_for(case: Case, restart: str | Path | None, comm) -> dict | None:
    """Read the checkpoint to restart from and check it belongs to this case (collective)."""
    if restart is None:
        return None
    from fem_runout.checkpoint import read_checkpoint

    tree = read_checkpoint(restart, comm)
    method = tree.get("meta", {}).get("method")
    if method != case.method:
        raise CaseError(f"--restart: the checkpoint '{restart}' is of method {method!r}, the "
                        f"case runs {case.method!r}; allowed: a checkpoint of the same method")
    return tree


def _checkpointer(case: Case, out: Path | None, comm):
    """Return the run's :class:`~fem_runout.checkpoint.Checkpointer` (None without outputs)."""
    if out is None:
        return None
    from fem_runout.checkpoint import Checkpointer

    spec = case.output.checkpoint
    meta = {"case": dump_resolved(case), "method": case.method, "ranks": comm.size}
    return Checkpointer(out / "checkpoints", spec.every, spec.keep, meta)


def _restore(case: Case, solver: Solver, callbacks: list, tree: dict) -> None:
    """Restore the solver and every restartable callback from a checkpoint (collective).

    A checkpoint of another mesh is refused with the ``domain`` keys that differ between its
    case and this one (an outline mesh also depends on ``domain.smoothing``, added after the
    first checkpoints were written: those were meshed without it).
    """
    from fem_runout.callbacks import restartable
    from fem_runout.checkpoint import MeshMismatch, check_nodes, domain_differences

    saved = tree.get("callbacks", {})
    nodal = [tree["solver"].get("nodes"), *(s.get("nodes") for s in saved.values()
                                            if isinstance(s, dict))]
    try:  # before anything is restored or written (DAMPM's state has no nodes)
        check_nodes(solver.V, next((n for n in nodal if isinstance(n, dict)), None))
    except MeshMismatch as exc:
        diff = domain_differences(tree.get("meta", {}).get("case", ""), dump_resolved(case))
        detail = "; ".join(diff) if diff else "the same domain keys: another DEM or mesh file"
        raise CaseError(f"--restart: {exc} ({detail}); allowed: a checkpoint written with "
                        "this case's domain") from None
    solver.load_state(tree["solver"])
    for name, cb in restartable(callbacks).items():
        if name in saved:
            cb.resume(saved[name])


def _prepare_out_dir(case: Case, comm, overwrite: bool, resume: bool = False) -> Path:
    out = case.output_dir
    bad = None
    if resume:
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        return out
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


def build_solver(case: Case, comm) -> Solver:
    """Build the solver of ``case.method`` from the method registry (collective)."""
    return methods.get(case.method).build(case, comm)


def run(
    case: Case | str | Path | dict,
    *,
    overwrite: bool = False,
    quiet: bool = True,
    write: bool = True,
    comm=None,
    callbacks: Sequence[Callback] = (),
    raise_errors: bool = True,
    restart: str | Path | None = None,
    stop=None,
) -> RunResult:
    """Run a case (collective on ``comm``, default COMM_WORLD): the one run path.

    The CLI, ``compare``, the hard cases and every bench command call this function; what is
    written and recorded is chosen by the arguments and by extra callbacks.

    Args:
        case: A validated case, or a path/mapping given to :func:`load_case`.
        overwrite: Replace a non-empty output folder.
        quiet: No progress bar and no summary.
        write: Write the output folder (fields, series, peaks, pictures).
        comm: MPI communicator.
        callbacks: Extra callbacks (:class:`~fem_runout.callbacks.Callback`), called after
            the built-in outputs and diagnostics.
        raise_errors: Raise :class:`~fem_runout.errors.SimulationError` when the state goes
            bad (NaN, negative depth); with False the run stops there and returns the last
            good state with :attr:`RunResult.error` set.
        restart: A checkpoint (``<output.dir>/checkpoints/checkpoint_<step>.h5``) to continue
            from, on any number of ranks; the outputs continue in the same folder.
        stop: Returns a signal number once the run should stop (checkpoint, outputs, then
            :class:`~fem_runout.errors.RunInterrupted`); the CLI passes its SIGTERM/SIGINT flag.

    Returns:
        The final state and diagnostics (arrays on rank 0).
    """
    from mpi4py import MPI

    from fem_runout.runner import Runner

    comm = comm or MPI.COMM_WORLD
    case = _validated(case)
    tree = _checkpoint_for(case, restart, comm)
    solver = build_solver(case, comm)
    out = _prepare_out_dir(case, comm, overwrite, resume=tree is not None) if write else None
    outputs = _Outputs(case, solver, out)
    every = [*outputs.callbacks, *callbacks]
    if tree is not None:
        _restore(case, solver, every, tree)
    elif not quiet:
        _say_mesh(case, solver, comm)
        _say_released(solver, comm)
    progress = _Progress(case.time.end_time, case.name) if (not quiet and comm.rank == 0) \
        else None
    runner = Runner(solver, schedule_of(case), every, progress,
                    checkpoints=_checkpointer(case, out, comm), stop=stop)
    if tree is not None and runner.checkpoints is not None:
        runner.checkpoints.resume_at(float(tree["runner"]["t"]))
    stopped: SimulationError | RunInterrupted | None = None
    try:
        info = runner.run(resume=None if tree is None else tree["runner"])
    except (SimulationError, RunInterrupted) as exc:  # the outputs of the last good state
        stopped, info = exc, runner.info
    result = outputs.result(case, runner, info, comm)
    if stopped is not None:
        if raise_errors or isinstance(stopped, RunInterrupted):
            raise stopped
        result.error = str(stopped)
    if not quiet and comm.rank == 0:
        _summary(result, comm.size)
    return result


def schedule_of(case: Case):
    """Return the runner's :class:`~fem_runout.runner.Schedule` for a case's time and output."""
    from fem_runout.runner import Schedule

    t, thr = case.time, case.output.front_threshold
    return Schedule(t.end_time, t.cfl, case.output.every, t.max_steps, t.dt_max,
                    t.rest_speed if t.auto else None, t.rest_duration, thr, t.rest_energy,
                    case.numerics.max_speed)


def _validated(case: Case | str | Path | dict) -> Case:
    """Return a :class:`Case` from any accepted input (terrain resolved)."""
    if not isinstance(case, Case):
        return load_case(case)
    if case.terrain.dem is not None and case.domain.extent is None:
        from fem_runout.terrain.resolve import resolve_terrain

        return resolve_terrain(case)  # a Case built without load_case
    return case


class _Outputs:
    """The built-in callbacks of a run and the :class:`RunResult` they produce."""

    def __init__(self, case: Case, solver: Solver, out: Path | None) -> None:
        from fem_runout.output import FieldWriter, PeakTracker, Pictures, SeriesRecorder
        from fem_runout.output.hazard import HazardMaps

        thr = case.output.front_threshold
        self.recorder = SeriesRecorder(out / "series.csv" if out else None, thr,
                                       case.material.density)
        self.peaks = PeakTracker(out, thr)
        self.hazard = HazardMaps(case, out if case.output.hazard else None,
                                 case.output.pictures)
        self.out = out
        self.callbacks: list = [self.recorder, self.peaks]
        if out is not None:
            self.callbacks.insert(0, FieldWriter(out, solver, threshold=case.numerics
                                                 .dry_tolerance, pvd=case.output.vtk))
            if case.output.pictures:
                self.callbacks.append(Pictures(out, case.name, self.recorder, self.peaks,
                                               threshold=thr))
            self.callbacks += methods.get(case.method).output_callbacks(out)
        self.callbacks.append(self.hazard)

    def result(self, case: Case, runner, info, comm) -> RunResult:
        """Gather the final state and write ``summary.json`` (collective)."""
        from fem_runout.output import gather_nodal

        solver = runner.solver
        final = gather_nodal(solver.V, {**{k: f.x.array for k, f in solver.fields.items()},
                                        "area": solver.lumped_mass})
        envelope = self.peaks.gathered()
        result = RunResult(series=self.recorder.series, wall_time=runner.wall_time,
                           steps=info.step, t=info.t, out_dir=self.out,
                           at_rest=runner.at_rest, particles=solver.n_particles,
                           cells=solver.mesh.topology.index_map(2).size_global)
        result.summary = {**self.hazard.summary, "t_end": info.t, "steps": info.step,
                          "at_rest": runner.at_rest, "wall_time": runner.wall_time,
                          "ranks": comm.size, "method": case.method,
                          "particles": result.particles}
        if self.out is not None and comm.rank == 0:
            (self.out / "summary.json").write_text(json.dumps(result.summary, indent=2) + "\n")
        if final is not None:
            for key in ("x", "y", "h", "hu", "hv", "z", "area"):
                setattr(result, key, final[key])
            result.peak_depth = envelope["peak_depth"]
            result.peak_speed = envelope["peak_speed"]
        return result


def _say_mesh(case: Case, solver: Solver, comm) -> None:
    """Print an outline mesh's size and origin (made by gmsh or kept) on rank 0."""
    from fem_runout.meshing.cache import last_origin

    origin = last_origin() if comm.rank == 0 and case.domain.kind == "outline" else None
    if origin is None:
        return
    cells = solver.mesh.topology.index_map(2).size_global
    where = "" if origin.folder is None else f"; kept in {origin.folder}"
    how = {"gmsh": f"meshed by gmsh in {origin.seconds:.1f} s{where}",
           "disk": f"from the mesh cache {origin.folder}",
           "process": "from this process's mesh cache"}[origin.source]
    print(f"mesh: {cells} quadrilaterals ({how})", flush=True)


def _say_released(solver, comm) -> None:
    """Print the released volume ``Σ M_i h_i`` on rank 0 (collective).

    An exact sum (:func:`~fem_runout.output.gather.exact_global_sum`): the digits printed do
    not depend on the rank count or on the CPU's BLAS kernels (a dot product's do).
    """
    from fem_runout.output.gather import exact_global_sum

    n = solver.V.dofmap.index_map.size_local
    volume = exact_global_sum(comm, solver.lumped_mass[:n] * solver.fields["h"].x.array[:n])
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
