"""Python API: ``load_case`` and ``run`` (collective), the same code path as the CLI."""

from __future__ import annotations

import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fem_runout.config import Case, dump_resolved, load_case
from fem_runout.errors import CaseError

IMPLEMENTED_METHODS = frozenset({"tg2"})

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
        particles: Number of particles of a particle method (the solver's ``n_particles``
            attribute at the end of the run), None for mesh methods.
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
    from fem_runout.runner import Runner, Schedule

    comm = comm or MPI.COMM_WORLD
    if not isinstance(case, Case):
        case = load_case(case)
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
    t = case.time
    schedule = Schedule(t.end, t.cfl, case.output.every, t.max_steps, t.dt_max)
    progress = _Progress(t.end, case.name) if (not quiet and comm.rank == 0) else None
    runner = Runner(solver, schedule, callbacks, progress)
    info = runner.run()
    final = gather_nodal(solver.V, {k: f.x.array for k, f in solver.fields.items()})
    envelope = peaks.gathered()
    result = RunResult(series=recorder.series, wall_time=runner.wall_time, steps=info.step,
                       t=info.t, out_dir=out, particles=getattr(solver, "n_particles", None))
    if final is not None:
        for key in ("x", "y", "h", "hu", "hv", "z"):
            setattr(result, key, final[key])
        result.peak_depth, result.peak_speed = envelope["peak_depth"], envelope["peak_speed"]
    if not quiet and comm.rank == 0:
        _summary(result, comm.size)
    return result


def _summary(result: RunResult, ranks: int) -> None:
    err = result.series.get("mass_error", np.array([np.nan]))
    print(
        f"done: {result.steps} steps to t = {result.t:.4g} s in {result.wall_time:.2f} s wall "
        f"on {ranks} rank(s); relative mass error {float(err[-1]):.2e}"
        + (f"; results in {result.out_dir}/" if result.out_dir else ""),
        flush=True,
    )
