"""The friction tests of the IMEX-RKC issue with ``method: mpm``: same setups, same tolerances.

The sheets are open downstream as for TG2-PC: DAMPM's open sides carry the pressure of the
fluid beyond (transmissive), so they launch no rarefaction into the probe window.
"""

import numpy as np

from tests.test_tg2_physics import G, _probe, _sheet


def test_voellmy_sheet_reaches_the_tanh_law():
    slope, mu, xi, h = 0.3, 0.1, 500.0, 1.0
    a, b = G * (slope - mu), G / (xi * h)
    t_end = 3.0 / np.sqrt(a * b)
    c = _sheet(slope, {"law": "voellmy", "mu": mu, "xi": xi}, end=t_end, method="mpm")
    t, u, _ = _probe(c)
    exact = np.sqrt(a / b) * np.tanh(np.sqrt(a * b) * t_end)
    print(f"DAMPM Voellmy sheet: u = {u[-1]:.4f}, exact {exact:.4f}, "
          f"rel. error {abs(u[-1] / exact - 1):.2e}, steps {len(t) - 1}")
    assert abs(u[-1] / exact - 1.0) < 5e-3


def test_coulomb_stop_time_and_no_creep():
    slope, mu, u0 = 0.1, 0.3, 5.0
    t_stop = u0 / (G * (mu - slope))
    c = _sheet(slope, {"law": "coulomb", "mu": mu}, u0=u0, end=2.0 * t_stop, method="mpm")
    t, u, umax = _probe(c)
    # at rest: the grid momentum is h times the mass-averaged particle velocity, exactly 0
    k = np.flatnonzero(np.abs(u) <= 1e-12)[0]
    rate = (u[k - 2] - u[k - 1]) / (t[k - 1] - t[k - 2])
    crossing = t[k - 1] + u[k - 1] / rate
    print(f"DAMPM Coulomb stop at {crossing:.4f} s, exact {t_stop:.4f} s; deceleration "
          f"{rate:.4f}, exact {G * (mu - slope):.4f}")
    assert abs(crossing / t_stop - 1.0) < 0.02
    assert t[k - 1] < t_stop <= t[k] + 1e-9
    assert np.all(np.diff(u[: k + 1]) <= 1e-12)
    assert np.abs(umax[k:]).max() <= 1e-12


def test_layer_below_yield_never_moves():
    c = _sheet(0.1, {"law": "coulomb", "phi_deg": 26.0}, end=3.0, method="mpm")
    t, u, umax = _probe(c)
    print("DAMPM max interior speed of a held layer:", umax.max())
    assert umax.max() <= 1e-12
