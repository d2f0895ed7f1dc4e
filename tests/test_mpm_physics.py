"""DAMPM's Coulomb stop (its own at-rest checks), for every method with particles; the Voellmy
sheet and the held layer run for every method in tests/test_tg2_physics.py.

The sheets are open downstream as for TG2-PC: DAMPM's open sides carry the pressure of the
fluid beyond (transmissive), so they launch no rarefaction into the probe window.
"""

import numpy as np
import pytest

from fem_runout.methods import METHODS
from tests.tg2_helpers import G, probe, sheet


@pytest.mark.parametrize("method", [m.name for m in METHODS.values() if m.particles])
def test_coulomb_stop_time_and_no_creep(method):
    slope, mu, u0 = 0.1, 0.3, 5.0
    t_stop = u0 / (G * (mu - slope))
    c = sheet(slope, {"law": "coulomb", "mu": mu}, u0=u0, end=2.0 * t_stop, method=method)
    t, u, umax = probe(c)
    # at rest: the grid momentum is h times the mass-averaged particle velocity, exactly 0
    k = np.flatnonzero(np.abs(u) <= 1e-12)[0]
    rate = (u[k - 2] - u[k - 1]) / (t[k - 1] - t[k - 2])
    crossing = t[k - 1] + u[k - 1] / rate
    print(f"{method} Coulomb stop at {crossing:.4f} s, exact {t_stop:.4f} s; deceleration "
          f"{rate:.4f}, exact {G * (mu - slope):.4f}")
    assert abs(crossing / t_stop - 1.0) < 0.02
    assert t[k - 1] < t_stop <= t[k] + 1e-9
    assert np.all(np.diff(u[: k + 1]) <= 1e-12)
    assert np.abs(umax[k:]).max() <= 1e-12

