"""Hard cases on 2 and 3 ranks (every implemented method): the serial criteria, and the same
steps, peak speed and final speed as the serial run, to the last bit."""

import pytest
from mpi4py import MPI

from fem_runout.bench.hard_cases import run_hard_case
from fem_runout.config import load_case
from tests.test_hard_cases import PARAMS

WORLD = MPI.COMM_WORLD


@pytest.mark.parametrize(("path", "method"), PARAMS)
def test_hard_case_in_parallel(path, method):
    r = run_hard_case(load_case(path, [("method", method)]), WORLD)
    if WORLD.rank == 0:
        print(f"{r.name} [{method}] on {WORLD.size} ranks: {r.steps} steps, volume error "
              f"{r.volume_error:.1e}, max speed {r.max_speed:.3g} / {r.speed_bound:.3g}")
    assert r.steps > 0
    assert r.failures == [], r.failures
    if WORLD.rank == 0:
        s = run_hard_case(load_case(path, [("method", method)]), MPI.COMM_SELF)
        assert (r.steps, r.t, r.max_speed, r.final_speed, r.min_h) == (
            s.steps, s.t, s.max_speed, s.final_speed, s.min_h)
