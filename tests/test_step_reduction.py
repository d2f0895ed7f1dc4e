"""The series' per-step diagnostics ride in the runner's two reductions of the step.

The max reduction of the health check carries the diagnostics' maxima, the kinetic energy's
sum reduction carries their exact folds: a recorded step sends no message of its own, and its
row has the bits of :func:`compute_diagnostics` (run on 1, 2 and 3 ranks through
``tests/mpi/test_output_mpi.py``).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.callbacks import StepReduction
from fem_runout.output.diagnostics import SERIES_COLUMNS, SeriesRecorder, compute_diagnostics
from fem_runout.runner import Runner, Schedule
from tests.counting_comm import CountingComm
from tests.fake_solver import fake_solver

THRESHOLD, RHO = 1e-3, 200.0


class SlidingBump:
    """Fake solver: a bump of depth that slides along x and slows down, a front that moves."""

    def __init__(self, comm) -> None:
        self.base = fake_solver(comm, {"h": lambda x, y: 0 * x, "hu": lambda x, y: 0 * x,
                                       "hv": lambda x, y: 0 * x, "z": lambda x, y: 0 * x},
                                cells=(12, 5))
        for name in ("comm", "mesh", "V", "fields", "lumped_mass", "outflow_volume",
                     "dried_volume", "flow_dofs"):
            setattr(self, name, getattr(self.base, name))
        # the nodes' grid positions (a dof's tabulated coordinates can differ in their last
        # bits with the cell it is tabulated from, and so with the partition)
        per_metre = np.array([12 / 4.0, 5 / 2.0])
        self.xy = np.round(self.V.tabulate_dof_coordinates()[:, :2] * per_metre) / per_metre
        # the nodes' dual areas from their coordinates: the same bits on any partition (the
        # stand-in's assembled mass adds a shared node's cells in the partition's order)
        side = [np.where((c == 0.0) | (c == top), 0.5, 1.0) for c, top in
                zip(self.xy.T, (4.0, 2.0), strict=True)]
        self.lumped_mass = side[0] * side[1] * (4.0 / 12) * (2.0 / 5)
        self.t = 0.0
        self._set()

    def _set(self) -> None:
        x, y = self.xy[:, 0], self.xy[:, 1]
        h = np.maximum(0.5 - (x - 0.8 - 0.3 * self.t) ** 2 - 0.5 * (y - 1.0) ** 2, 0.0) / 3.0
        self.fields["h"].x.array[:] = h
        self.fields["hu"].x.array[:] = h * np.exp(-self.t) * (1.0 + x)
        self.fields["hv"].x.array[:] = h * 0.1 * y

    def stable_dt(self) -> float:
        return 0.1

    def advance(self, dt: float) -> None:
        self.t += dt
        self._set()

    def snapshot(self) -> float:
        return self.t

    def restore(self, snap: float) -> None:
        self.t = snap
        self._set()

    def health(self, also_max=None) -> None:
        """One max reduction, as the solvers' checks (their flag and next limits)."""
        values = np.concatenate([[0.0], [] if also_max is None else also_max])
        self.comm.Allreduce(MPI.IN_PLACE, values, op=MPI.MAX)
        if also_max is not None:
            also_max[...] = values[1:]
        return None


class ReferenceDiagnostics:
    """Callback: :func:`compute_diagnostics` after every step (its own two reductions)."""

    def __init__(self) -> None:
        self.rows: list[dict[str, float]] = []

    def start(self, solver, info) -> None:
        self.rows.append(compute_diagnostics(solver, THRESHOLD, RHO))

    def step(self, solver, info) -> None:
        self.rows.append(compute_diagnostics(solver, THRESHOLD, RHO))

    def output(self, solver, info) -> None:
        """Nothing at outputs."""

    def finish(self, solver, info) -> None:
        """Nothing at the end."""


SCHEDULES = {
    "rest energy": dict(rest_speed=1e-9, rest_duration=50.0, rest_energy=1e-6, max_speed=1e3),
    "rest speed": dict(rest_speed=1e-9, rest_duration=50.0),
    "nothing watched": {},
}


@pytest.mark.parametrize("watch", list(SCHEDULES))
def test_a_recorded_step_sends_no_message_of_its_own(watch) -> None:
    counts = []
    for with_series in (False, True):
        solver = SlidingBump(MPI.COMM_WORLD)
        solver.comm = CountingComm(solver.comm)
        recorder = SeriesRecorder(None, THRESHOLD, RHO)
        runner = Runner(solver, Schedule(2.0, 1.0, 10.0, **SCHEDULES[watch]),
                        [recorder] if with_series else [])
        info = runner.run()
        counts.append(solver.comm.total)
        assert info.step == 20
    assert isinstance(recorder, StepReduction)
    # without the recorder: the health check, and the rest energy's sum, each step
    assert counts[0] == {"rest energy": 2, "rest speed": 1, "nothing watched": 1}[watch] * 20
    # with it: the initial volume and the first row (two reductions each), then each step the
    # health check and one sum (the energy's, with it); its own two used to come on top
    assert counts[1] == 4 + 2 * 20
    assert len(recorder.series["t"]) == 21


@pytest.mark.parametrize("watch", list(SCHEDULES))
def test_the_rows_are_those_of_compute_diagnostics(watch) -> None:
    solver = SlidingBump(MPI.COMM_WORLD)
    recorder, reference = SeriesRecorder(None, THRESHOLD, RHO), ReferenceDiagnostics()
    Runner(solver, Schedule(2.0, 1.0, 10.0, **SCHEDULES[watch]), [recorder, reference]).run()
    series = recorder.series
    assert series["front_x"][-1] > series["front_x"][1] > 0.0  # the bump moved, wet and dry
    assert series["kinetic_energy"][1] > series["kinetic_energy"][-1] > 0.0
    for name in SERIES_COLUMNS:
        if name in ("t", "dt", "mass_error"):
            continue
        want = np.array([row[name] for row in reference.rows])
        assert np.array_equal(series[name], want, equal_nan=True), name
