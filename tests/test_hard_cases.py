"""Hard cases for stability (cases/hard/), every implemented method, one rank.

Criteria (fem_runout.bench.hard_cases): end time reached, no NaN, h >= 0 after every step,
|V + outflow - V0| <= 1e-10 V0 over the run, max speed <= sqrt(2 g ΔZ) + 2 sqrt(g h_max) over
the run, and the pit case at rest at the end (max speed <= 1e-3 m/s).

Known failures are marked ``xfail(strict=True)`` with what fails: the criteria are not
weakened, and the mark turns into an error as soon as the case passes.
"""

import pytest
from mpi4py import MPI

from fem_runout.bench.hard_cases import (
    KNOWN_FAILURES,
    REST_SPEED,
    hard_case_files,
    run_hard_case,
)
from fem_runout.config import load_case
from fem_runout.methods import method_names

PARAMS = [
    pytest.param(path, method, id=f"{path.stem}-{method}",
                 marks=[pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[(path.stem, method)])]
                 if (path.stem, method) in KNOWN_FAILURES else [])
    for path in hard_case_files() for method in sorted(method_names())
]


def test_there_are_eight_hard_cases():
    assert len(hard_case_files()) == 8


@pytest.mark.parametrize(("path", "method"), PARAMS)
def test_hard_case(path, method):
    case = load_case(path, [("method", method)])
    r = run_hard_case(case, MPI.COMM_SELF)
    print(f"{r.name} [{method}]: t {r.t:.3g}/{r.end:.3g} s, {r.steps} steps, min h {r.min_h:.2e}, "
          f"volume error {r.volume_error:.1e}, max speed {r.max_speed:.3g} (bound "
          f"{r.speed_bound:.3g}), final speed {r.final_speed:.2e}")
    assert r.steps > 0
    assert r.failures == [], r.failures


@pytest.mark.parametrize("method", method_names())
def test_a_hard_case_with_end_auto_stops_at_rest(method):
    """The pit through the one run path with ``end: auto``: it stops at rest, before ``max``."""
    path = next(p for p in hard_case_files() if p.stem == "pit")
    case = load_case(path, [("method", method), ("time.end", "auto"), ("time.max", 40.0),
                            ("time.rest_speed", REST_SPEED), ("time.rest_duration", 2.0)])
    r = run_hard_case(case, MPI.COMM_SELF)
    print(f"pit, end: auto [{method}]: stopped at t = {r.t:.3g} s (max {r.end:g}), "
          f"final speed {r.final_speed:.2e}")
    assert r.at_rest and r.t < r.end
    assert r.final_speed <= REST_SPEED
    assert r.failures == [], r.failures
