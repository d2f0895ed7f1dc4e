"""Films thinner than the dry tolerance dry out (TG2-PC), continuously and with their volume
counted: fewer wet nodes behind a flow, the same hazard answer, the balance exact."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config.loader import load_case
from fem_runout.tg2.compact import dry_films

CASES = Path(__file__).resolve().parents[1] / "cases"
COMM = MPI.COMM_SELF
TOL = 1e-6


def _state(h: np.ndarray) -> np.ndarray:
    q = np.empty((h.size, 3))
    q[:, 0], q[:, 1], q[:, 2] = h, 0.3 * h, -2.0 * h  # velocity (0.3, -2) where h > 0
    return q


def test_the_map_dries_films_keeps_their_velocity_and_counts_owned_volume():
    h = np.array([-1e-3, 0.0, 1e-12, 2.5e-7, 0.5 * TOL, TOL, 2 * TOL, 1.0, 3e-7])
    q = _state(h)
    m = np.linspace(1.0, 2.0, h.size)
    out = q.copy()
    owned = h.size - 1  # the last row is a ghost: dried, but not counted
    dried = dry_films(out, TOL, m, owned)
    film = (h > 0.0) & (h < TOL)
    np.testing.assert_array_equal(out[~film], q[~film])  # negative, zero and deep: untouched
    np.testing.assert_allclose(out[film, 0], h[film] ** 2 / TOL, rtol=1e-15)
    np.testing.assert_allclose(out[film, 1] / out[film, 0], 0.3, rtol=1e-13)
    np.testing.assert_allclose(out[film, 2] / out[film, 0], -2.0, rtol=1e-13)
    counted = film & (np.arange(h.size) < owned)
    assert abs(dried - np.sum(m[counted] * (h[counted] - out[counted, 0]))) <= 1e-15 * TOL


def test_the_map_is_continuous_at_the_tolerance_and_reaches_exact_zero():
    """Lipschitz (slope <= 2) across ``h = tol``: no switch on round-off; a film left alone
    squares its ratio to the tolerance each call, down to an exact zero (the underflow)."""
    eps = 1e-14
    q = _state(TOL * np.array([1.0 - eps, 1.0, 1.0 + eps]))
    dry_films(q, TOL, np.ones(3), 3)
    assert np.abs(np.diff(q[:, 0])).max() <= 2.0 * eps * TOL * 1.01  # 1 %: the rounding
    film = _state(np.array([0.5 * TOL]))
    calls = 0
    while film[0, 0] > 0.0:
        dry_films(film, TOL, np.ones(1), 1)
        calls += 1
    assert calls <= 12  # 0.5^(2^k) underflows below 4.9e-324 once 2^k > 1075
    assert film[0, 0] == 0.0 and film[0, 1] == 0.0 and film[0, 2] == 0.0


def test_films_dry_behind_a_flow_with_the_same_hazard_answer():
    """The rough-terrain hard case with the default dry tolerance against one so small that
    only denormal films dry: fewer wet nodes at the end, run-out, affected area and peak
    depth within the 1 % of issue 16, and volume + outflow + dried exact every step."""
    def go(tol: str):
        case = load_case(CASES / "hard" / "rough_terrain.yaml",
                         [f"numerics.dry_tolerance={tol}", "output.front_threshold=0.01"])
        return run(case, write=False, comm=COMM)

    dry, kept = go("1e-6"), go("1e-300")
    wet = {k: int(np.count_nonzero(r.h > 0.0)) for k, r in (("dry", dry), ("kept", kept))}
    films = {k: int(np.count_nonzero((r.h > 0.0) & (r.h < TOL)))
             for k, r in (("dry", dry), ("kept", kept))}
    print("wet nodes", wet, "films", films, "dried", dry.summary["dried_volume"])
    assert wet["dry"] < wet["kept"] and films["dry"] < films["kept"]
    assert dry.summary["dried_volume"] > 0.0
    for key in ("runout_length", "affected_area", "peak_depth_max"):
        assert abs(dry.summary[key] - kept.summary[key]) <= 0.01 * kept.summary[key], key
    s = dry.series
    balance = s["volume"] + s["outflow"] + s["dried"] - s["volume"][0]
    assert np.abs(balance).max() <= 1e-12 * s["volume"][0]
