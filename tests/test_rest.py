"""``time.end: auto``: the runner stops once the largest speed stays below rest_speed."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.config import load_case
from fem_runout.errors import CaseError, RunInterrupted
from fem_runout.runner import Runner, Schedule, max_speed
from tests.counting_comm import CountingComm
from tests.fake_solver import fake_solver


class _Decaying:
    """Fake solver: depth 1, speed ``exp(-t)`` along x."""

    def __init__(self) -> None:
        self.base = fake_solver(MPI.COMM_WORLD, {"h": lambda x, y: 1.0 + 0 * x,
                                                 "hu": lambda x, y: 1.0 + 0 * x,
                                                 "hv": lambda x, y: 0 * x, "z": lambda x, y: 0 * x})
        for name in ("comm", "mesh", "V", "fields", "lumped_mass", "outflow_volume",
                     "dried_volume", "flow_dofs"):
            setattr(self, name, getattr(self.base, name))
        self.t = 0.0

    def stable_dt(self) -> float:
        return 0.1

    def advance(self, dt: float) -> None:
        self.t += dt
        self.fields["hu"].x.array[:] = np.exp(-self.t)

    def snapshot(self) -> float:
        return self.t

    def restore(self, snap: float) -> None:
        self.t = snap

    def health(self, also_max=None) -> None:
        if also_max is not None:
            self.comm.Allreduce(MPI.IN_PLACE, also_max, op=MPI.MAX)
        return None


def test_stops_after_rest_duration() -> None:
    solver = _Decaying()
    assert max_speed(solver, 1e-3) == pytest.approx(1.0)
    runner = Runner(solver, Schedule(50.0, 1.0, 10.0, rest_speed=0.01, rest_duration=1.0), [])
    info = runner.run()
    first_rest = np.ceil(np.log(100) / 0.1) * 0.1  # first step with exp(-t) < 0.01: t = 4.7
    assert runner.at_rest
    assert info.t == pytest.approx(first_rest + 1.0, abs=1e-9)


def test_runs_to_max_without_rest() -> None:
    runner = Runner(_Decaying(), Schedule(3.0, 1.0, 1.0, rest_speed=0.01, rest_duration=1.0), [])
    info = runner.run()
    assert not runner.at_rest and info.t == pytest.approx(3.0)


def test_auto_end_keys() -> None:
    base = {"name": "a", "domain": {"extent": [0, 1, 0, 1], "cells": [1, 1]},
            "initial": {"depth": "1"}}
    case = load_case({**base, "time": {"end": "auto", "max": 600}})
    assert case.time.auto and case.time.end_time == 600.0 and case.output.every == 60.0
    assert (case.time.rest_speed, case.time.rest_duration) == (0.01, 5.0)
    with pytest.raises(CaseError, match="time.max: only used with end: auto"):
        load_case({**base, "time": {"end": 2, "max": 600}})
    with pytest.raises(CaseError, match="time.end: must be a number or auto, got 'soon'"):
        load_case({**base, "time": {"end": "soon"}})


def test_energy_criterion() -> None:
    # speed exp(-t): energy ∝ exp(-2t) < 1e-2 × peak (t = 0.1) from t = 0.1 + ln(10) = 2.40
    schedule = Schedule(50.0, 1.0, 10.0, rest_speed=1e-6, rest_duration=0.5, rest_energy=1e-2)
    runner = Runner(_Decaying(), schedule, [])
    info = runner.run()
    assert runner.at_rest
    assert info.t == pytest.approx(2.5 + 0.5, abs=1e-9)


@pytest.mark.parametrize("energy, per_step", [(None, 1), (1e-2, 2)])
def test_a_step_is_checked_in_one_message(energy, per_step) -> None:
    """Health, the speed limit, the rest speed and the stop signal share one max reduction
    (the solver's health check carries them); the kinetic energy's exact sum adds one."""
    solver = _Decaying()
    solver.comm = CountingComm(solver.comm)
    schedule = Schedule(1.0, 1.0, 10.0, rest_speed=1e-6, rest_duration=5.0, rest_energy=energy,
                        max_speed=100.0)
    asked = []
    info = Runner(solver, schedule, [], stop=lambda: asked.append(1) or 0).run()
    assert info.step >= 10 and len(asked) == info.step
    assert solver.comm.total == per_step * info.step


def test_a_signal_on_one_check_stops_the_run() -> None:
    solver = _Decaying()
    calls = iter([0, 0, 15])
    with pytest.raises(RunInterrupted) as stopped:
        Runner(solver, Schedule(5.0, 1.0, 10.0, max_speed=100.0), [],
               stop=lambda: next(calls, 15)).run()
    assert stopped.value.signum == 15 and stopped.value.step == 3
