"""Hard cases on 2 and 3 ranks (every implemented method): the serial criteria, and the same
steps, peak speed and final speed as the serial run, to the last bit."""

import functools

import pytest
from mpi4py import MPI

from fem_runout.bench.hard_cases import run_hard_case
from fem_runout.config import load_case
from tests.serial_runs import serial_references
from tests.test_hard_cases import PARAMS

WORLD = MPI.COMM_WORLD


def _key(path, method):
    return path.stem, method


def _serial(path, method):
    return run_hard_case(load_case(path, [("method", method)]), MPI.COMM_SELF)


@pytest.fixture(scope="module")
def serial():
    """The serial runs of every hard case, dealt over the ranks (rank 0 holds them)."""
    return serial_references(WORLD, {_key(*p.values): functools.partial(_serial, *p.values)
                                     for p in PARAMS})


@pytest.mark.parametrize(("path", "method"), PARAMS)
def test_hard_case_in_parallel(path, method, serial):
    r = run_hard_case(load_case(path, [("method", method)]), WORLD)
    if WORLD.rank == 0:
        print(f"{r.name} [{method}] on {WORLD.size} ranks: {r.steps} steps, volume error "
              f"{r.volume_error:.1e}, max speed {r.max_speed:.3g} / {r.speed_bound:.3g}")
    assert r.steps > 0
    assert r.failures == [], r.failures
    if WORLD.rank == 0:
        s = serial[_key(path, method)]
        assert (r.steps, r.t, r.max_speed, r.final_speed, r.min_h) == (
            s.steps, s.t, s.max_speed, s.final_speed, s.min_h)
