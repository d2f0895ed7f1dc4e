"""Global diagnostics of the state: volume balance, energy, extent, and peak envelopes."""

from __future__ import annotations

import csv
import functools
from pathlib import Path
from typing import TYPE_CHECKING

from mpi4py import MPI  # before dolfinx

# isort: split

import numpy as np
from dolfinx import fem, io

from fem_runout.callbacks import flow_index
from fem_runout.exact_sum import fold_extractors
from fem_runout.mesh import node_coordinates
from fem_runout.output.diagnostics_kernel import diagnostic_folds, diagnostic_maxima
from fem_runout.output.envelopes import fold_envelopes
from fem_runout.output.gather import gather_nodal

if TYPE_CHECKING:
    from fem_runout.callbacks import StepInfo
    from fem_runout.solver_api import Solver

__all__ = ["SERIES_COLUMNS", "DiagnosticTerms", "PeakTracker", "SeriesRecorder",
           "compute_diagnostics", "nodal_speed"]

SERIES_COLUMNS: tuple[str, ...] = (
    "t",
    "dt",
    "volume",
    "mass_error",
    "kinetic_energy",
    "max_depth",
    "max_speed",
    "wet_area",
    "front_x",
    "outflow",
    "dried",
)


def nodal_speed(h: np.ndarray, hu: np.ndarray, hv: np.ndarray, threshold: float) -> np.ndarray:
    """Depth-averaged speed ``|(hu, hv)| / h`` where ``h > threshold``, 0 elsewhere.

    Args:
        h: Nodal depth [m].
        hu: Nodal x discharge [m^2/s].
        hv: Nodal y discharge [m^2/s].
        threshold: Dry threshold [m].

    Returns:
        Nodal speed [m/s], same shape as ``h``.
    """
    wet = h > threshold
    speed = np.zeros_like(h, dtype=np.float64)
    speed[wet] = np.hypot(hu[wet], hv[wet]) / h[wet]
    return speed


@functools.lru_cache(maxsize=8)
def _owned_range(n: int) -> np.ndarray:
    """``arange(n)`` (read-only, kept: the owned dofs when the flow covers most of them)."""
    out = np.arange(n, dtype=np.int64)
    out.flags.writeable = False
    return out


def owned_x(solver: Solver) -> np.ndarray:
    """Return the x coordinate of the owned nodes (for :func:`compute_diagnostics`'s ``x``)."""
    n = solver.V.dofmap.index_map.size_local
    return node_coordinates(solver.V)[:n, 0].copy()


def compute_diagnostics(solver: Solver, threshold: float, density: float,
                        x: np.ndarray | None = None) -> dict[str, float]:
    """Global diagnostics of the current state (collective; owned dofs only).

    Two reductions: the maxima (:meth:`DiagnosticTerms.maxima`), then the exact sums' folds
    (:meth:`DiagnosticTerms.folds`). After a step the runner carries both in its own two
    reductions instead (:class:`SeriesRecorder` is a
    :class:`~fem_runout.callbacks.StepReduction`).

    Args:
        solver: The solver (see :class:`fem_runout.solver_api.Solver`).
        threshold: Dry threshold [m]: nodes with ``h > threshold`` are wet.
        density: Bulk density [kg/m^3] for the kinetic energy.
        x: :func:`owned_x` of the solver, if already known (saves tabulating it).

    Returns:
        ``volume`` [m^3] (``sum m_i h_i``), ``kinetic_energy`` [J] (``sum m_i rho/2 |hu|^2/h``
        over wet nodes), ``max_depth`` [m], ``max_speed`` [m/s] (over wet nodes, 0 if none),
        ``wet_area`` [m^2], ``front_x`` [m] (largest x of a wet node, nan if none) and
        ``outflow`` [m^3] (``solver.outflow_volume``), ``dried`` [m^3]
        (``solver.dried_volume``). The same bits on every rank, any rank count and any CPU
        (the sums are exact-fold sums, :func:`fem_runout.exact_sum.exact_totals`).
    """
    comm = solver.comm
    terms = DiagnosticTerms(solver, threshold, density, owned_x(solver) if x is None else x)
    maxima = terms.maxima()
    comm.Allreduce(MPI.IN_PLACE, maxima, op=MPI.MAX)
    folds = terms.folds(maxima)
    comm.Allreduce(MPI.IN_PLACE, folds, op=MPI.SUM)
    return terms.result(maxima, folds)


class DiagnosticTerms:
    """One rank's parts of :func:`compute_diagnostics` for one state (no MPI).

    :meth:`maxima` (maximise over the ranks), :meth:`folds` of the reduced maxima (sum over
    the ranks), :meth:`result` of both reduced: any message may carry them, the bits are
    those of :func:`compute_diagnostics`.

    Args:
        solver: The solver.
        threshold: Dry threshold [m].
        density: Bulk density [kg/m^3].
        x: :func:`owned_x` of the solver.
    """

    def __init__(self, solver: Solver, threshold: float, density: float,
                 x: np.ndarray) -> None:
        idx = flow_index(solver)
        self.idx = _owned_range(idx.stop) if isinstance(idx, slice) \
            else np.asarray(idx, dtype=np.int64)
        self.solver, self.x = solver, x
        self.threshold, self.density = float(threshold), float(density)
        self.mass = np.asarray(solver.lumped_mass, dtype=np.float64)
        self.h, self.hu, self.hv = (solver.fields[k].x.array.real for k in ("h", "hu", "hv"))

    def maxima(self) -> np.ndarray:
        """(6,) this rank's bounds of the three sums' terms, largest depth, speed and x."""
        return diagnostic_maxima(self.idx, self.x, self.mass, self.h, self.hu, self.hv,
                                 self.threshold, self.density,
                                 self.solver.V.dofmap.index_map.size_local > 0)

    def folds(self, maxima: np.ndarray) -> np.ndarray:
        """(6,) this rank's folds of the three sums, from :meth:`maxima` over the ranks."""
        ext = fold_extractors(maxima[:3], self.solver.V.dofmap.index_map.size_global)
        return diagnostic_folds(self.idx, self.mass, self.h, self.hu, self.hv, self.threshold,
                                self.density, ext)

    def result(self, maxima: np.ndarray, folds: np.ndarray) -> dict[str, float]:
        """Return the diagnostics of :meth:`maxima` and :meth:`folds`, both reduced."""
        sums = folds[0::2] + folds[1::2]  # as exact_totals: every partial sum exact
        top = maxima[3:]
        solver = self.solver
        return {
            "volume": float(sums[0]),
            "kinetic_energy": float(sums[1]),
            "max_depth": float(top[0]),
            "max_speed": float(top[1]),
            "wet_area": float(sums[2]),
            "front_x": float(top[2]) if np.isfinite(top[2]) else float("nan"),
            "outflow": float(solver.outflow_volume),
            "dried": float(solver.dried_volume),
        }


class SeriesRecorder:
    """Callback recording the time series of :func:`compute_diagnostics` to a CSV file.

    One row per recorded state (the initial state and every step) with the columns
    :data:`SERIES_COLUMNS`; ``mass_error = (volume + outflow + dried - V0) / V0`` with ``V0`` the
    initial volume (the absolute error if ``V0 == 0``). The CSV is written on rank 0 at every
    output and at finish, so a crashed run keeps its series. A step's row rides in the
    runner's two reductions of the step (a :class:`~fem_runout.callbacks.StepReduction`:
    :meth:`step_maxima`, :meth:`step_sums`, :meth:`step_reduced`); without them :meth:`step`
    reduces it itself (:func:`compute_diagnostics`), with the same bits.
    """

    def __init__(self, path: str | Path | None, threshold: float, density: float) -> None:
        """Create the recorder.

        Args:
            path: CSV file to write (its folder is created on rank 0 when writing), or None
                to keep the series in memory only.
            threshold: Dry threshold [m].
            density: Bulk density [kg/m^3].
        """
        self.path = None if path is None else Path(path)
        self.threshold = float(threshold)
        self.density = float(density)
        self.initial_volume = float("nan")
        self._columns: dict[str, list[float]] = {name: [] for name in SERIES_COLUMNS}
        self._last_step: int | None = None
        self._rank = 0
        self._x: np.ndarray | None = None
        self._resumed = False
        self._terms: DiagnosticTerms | None = None  # the step's, between the reductions
        self._diag: dict[str, float] | None = None  # the step's, reduced by the runner

    @property
    def series(self) -> dict[str, np.ndarray]:
        """The recorded columns as float arrays (the same on every rank)."""
        return {name: np.asarray(col, dtype=np.float64) for name, col in self._columns.items()}

    def step_maxima(self, solver: Solver) -> np.ndarray:
        """Return this rank's maxima of the state after the step (no MPI)."""
        self._terms = DiagnosticTerms(solver, self.threshold, self.density, self._x)
        self._diag = None
        return self._terms.maxima()

    def step_sums(self, solver: Solver, maxima: np.ndarray) -> np.ndarray:
        """Return this rank's folds of the step's sums, from the reduced maxima (no MPI)."""
        return self._terms.folds(maxima)

    def step_reduced(self, solver: Solver, maxima: np.ndarray, sums: np.ndarray) -> None:
        """Keep the step's diagnostics for :meth:`step` (both reduced over the ranks)."""
        self._diag, self._terms = self._terms.result(maxima, sums), None

    def _record(self, solver: Solver, info: StepInfo) -> None:
        """Append one row for the current state (collective unless the runner reduced it)."""
        diag, self._diag = self._diag, None
        if diag is None:
            diag = compute_diagnostics(solver, self.threshold, self.density, self._x)
        v0 = self.initial_volume
        balance = diag["volume"] + diag["outflow"] + diag["dried"] - v0
        row = {"t": info.t, "dt": info.dt, **diag}
        row["mass_error"] = balance / v0 if v0 != 0.0 else balance
        for name in SERIES_COLUMNS:
            self._columns[name].append(float(row[name]))
        self._last_step = info.step

    def write_csv(self) -> None:
        """Write the series to :attr:`path` (rank 0 only; nothing without a path)."""
        if self._rank != 0 or self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        with tmp.open("w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(SERIES_COLUMNS)
            for row in zip(*(self._columns[name] for name in SERIES_COLUMNS), strict=True):
                writer.writerow([repr(v) for v in row])
        tmp.replace(self.path)

    def save_state(self) -> dict:
        """Return the series so far (the same on every rank) for a checkpoint."""
        return {"columns": {k: np.asarray(v, dtype=np.float64) for k, v in self._columns.items()},
                "initial_volume": self.initial_volume,
                "last_step": -1 if self._last_step is None else self._last_step}

    def resume(self, state: dict) -> None:
        """Continue the series of a checkpoint (before :meth:`start`)."""
        self._columns = {k: np.asarray(state["columns"][k], dtype=np.float64).tolist()
                         for k in SERIES_COLUMNS}
        self.initial_volume = float(state["initial_volume"])
        self._last_step = None if state["last_step"] < 0 else int(state["last_step"])
        self._resumed = True

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Record the initial volume and the first row (resumed: keep the series so far)."""
        self._rank = solver.comm.rank
        self._x = owned_x(solver)
        if self._resumed:
            return
        self.initial_volume = compute_diagnostics(solver, self.threshold, self.density,
                                                  self._x)["volume"]
        self._record(solver, info)

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Record a row after a step."""
        self._record(solver, info)

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Rewrite the CSV so far."""
        self.write_csv()

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Record the final state if not yet recorded, and write the CSV."""
        self._diag = None  # a step's that was never recorded (the state went bad)
        if self._last_step != info.step:
            self._record(solver, info)
        self.write_csv()


class PeakTracker:
    """Callback tracking, per node, the running maxima of depth and speed.

    Updated at start and after every step on the owned nodes (no communication). At finish
    the envelopes are written as Q1 functions ``peak_depth`` and ``peak_speed`` to
    ``out_dir/peaks.bp`` (VTX) if ``out_dir`` is given.
    """

    def __init__(self, out_dir: str | Path | None, threshold: float, engine: str = "BP4") -> None:
        """Create the tracker.

        Args:
            out_dir: Folder for ``peaks.bp``; ``None`` to write nothing.
            threshold: Dry threshold [m] for the speed.
            engine: ADIOS2 engine of the VTX file.
        """
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.threshold = float(threshold)
        self.engine = engine
        self.peak_depth = np.zeros(0)
        self.peak_speed = np.zeros(0)
        self._V: fem.FunctionSpace | None = None
        self._resume: dict | None = None

    def _update(self, solver: Solver) -> None:
        """Fold the current state into the envelopes (on the flow's dofs: zero elsewhere)."""
        h, hu, hv = (solver.fields[k].x.array.real for k in ("h", "hu", "hv"))
        fold_envelopes(solver.flow_dofs(), h, hu, hv, self.threshold, self.peak_depth,
                       self.peak_speed)

    def functions(self) -> tuple[fem.Function, fem.Function]:
        """Return the envelopes as Q1 functions ``peak_depth``, ``peak_speed`` (collective).

        Returns:
            The two functions, ghost values updated.

        Raises:
            RuntimeError: If called before :meth:`start`.
        """
        if self._V is None:
            raise RuntimeError("PeakTracker.functions() called before start()")
        out = []
        for name, values in (("peak_depth", self.peak_depth), ("peak_speed", self.peak_speed)):
            f = fem.Function(self._V, name=name)
            f.x.array[: values.size] = values
            f.x.scatter_forward()
            out.append(f)
        return out[0], out[1]

    def gathered(self) -> dict[str, np.ndarray] | None:
        """Gather the envelopes to rank 0 (see :func:`gather_nodal`; collective).

        Returns:
            On rank 0 ``x``, ``y``, ``peak_depth``, ``peak_speed``; ``None`` elsewhere.

        Raises:
            RuntimeError: If called before :meth:`start`.
        """
        if self._V is None:
            raise RuntimeError("PeakTracker.gathered() called before start()")
        return gather_nodal(self._V, {"peak_depth": self.peak_depth, "peak_speed": self.peak_speed})

    def save_state(self) -> dict:
        """Return the envelopes in the global node order (collective; rank 0 has them)."""
        return {"nodes": self.gathered()}

    def resume(self, state: dict) -> None:
        """Continue a checkpoint's envelopes (restored at :meth:`start`)."""
        self._resume = state

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Initialise the envelopes with the initial state (or the checkpoint's)."""
        self._V = solver.V
        n = solver.V.dofmap.index_map.size_local
        self.peak_depth = np.zeros(n)  # depths are >= 0; zero outside the flow
        self.peak_speed = np.zeros(n)
        if self._resume is not None:
            from fem_runout.checkpoint import scatter_nodal

            local = scatter_nodal(solver.V, self._resume["nodes"])
            self.peak_depth[:], self.peak_speed[:] = local["peak_depth"][:n], \
                local["peak_speed"][:n]
            self._resume = None
        self._update(solver)

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Fold the new state into the envelopes."""
        self._update(solver)

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do at output times."""

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Write ``peaks.bp`` (collective)."""
        if self.out_dir is None:
            return
        if solver.comm.rank == 0:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        solver.comm.barrier()
        peak_depth, peak_speed = self.functions()
        writer = io.VTXWriter(
            solver.comm, self.out_dir / "peaks.bp", [peak_depth, peak_speed], engine=self.engine
        )
        try:
            writer.write(info.t)
        finally:
            writer.close()
