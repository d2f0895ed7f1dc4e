"""Friction and Bingham rheology in the split IMEX-RKC TG2-PC solver (seed §2.1, §3.1.1–2)."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.methods import METHODS, method_names
from fem_runout.references import shear_decay
from tests.tg2_helpers import G, case, lake_errors, probe, sheet

COMM = MPI.COMM_SELF


@pytest.mark.parametrize("method", method_names())
def test_voellmy_sheet_reaches_the_tanh_law(method):
    slope, mu, xi, h = 0.3, 0.1, 500.0, 1.0
    a, b = G * (slope - mu), G / (xi * h)
    t_end = 3.0 / np.sqrt(a * b)
    c = sheet(slope, {"law": "voellmy", "mu": mu, "xi": xi}, end=t_end, method=method)
    t, u, _ = probe(c)
    exact = np.sqrt(a / b) * np.tanh(np.sqrt(a * b) * t_end)
    print(f"{method} Voellmy sheet at 3 relaxation times: u = {u[-1]:.4f}, exact "
          f"{exact:.4f}, rel. error {abs(u[-1] / exact - 1):.2e}, steps {len(t) - 1}")
    assert abs(u[-1] / exact - 1.0) < 5e-3


@pytest.mark.parametrize("method", [m.name for m in METHODS.values() if not m.particles])
def test_coulomb_stop_time_and_no_creep(method):
    slope, mu, u0 = 0.1, 0.3, 5.0
    t_stop = u0 / (G * (mu - slope))
    c = sheet(slope, {"law": "coulomb", "mu": mu}, u0=u0, end=2.0 * t_stop, method=method)
    t, u, umax = probe(c)
    k = np.flatnonzero(u == 0.0)[0]  # first step that ends at rest
    # the stop lies between steps: zero crossing of the (linear) deceleration before it
    rate = (u[k - 2] - u[k - 1]) / (t[k - 1] - t[k - 2])
    crossing = t[k - 1] + u[k - 1] / rate
    print(f"Coulomb stop at {crossing:.4f} s (first step at rest ends at {t[k]:.4f} s), "
          f"exact {t_stop:.4f} s; deceleration {rate:.4f}, exact {G * (mu - slope):.4f}")
    assert abs(crossing / t_stop - 1.0) < 0.02
    assert t[k - 1] < t_stop <= t[k] + 1e-9
    assert np.all(np.diff(u[: k + 1]) <= 0.0)  # decelerates, never reverses
    assert np.abs(umax[k:]).max() <= 1e-12  # every interior node stays at rest


@pytest.mark.parametrize("method", method_names())
def test_layer_below_yield_never_moves(method):
    c = sheet(0.1, {"law": "coulomb", "phi_deg": 26.0}, end=3.0, method=method)
    t, u, umax = probe(c)
    print(f"{method} max interior speed of a held layer:", umax.max())
    assert umax.max() <= 1e-12


def _shear(mu, tau, ny, end=1.0):
    """The shear-decay reference case (fem_runout.references.shear_decay)."""
    return load_case(shear_decay.case_dict(ny, mu, tau, end, G))


def _decay_rate(c, end=1.0):
    r = run(c, write=False, comm=COMM)
    return shear_decay.measured_rate(r.x, r.y, r.h, r.hu, end), r


def test_bingham_viscous_shear_mode_decays_at_mu_k2_over_rho():
    mu, rho, k = 500.0, 1000.0, 2 * np.pi / 10.0
    exact = mu / rho * k * k
    rates = [_decay_rate(_shear(mu, 0.0, ny))[0] for ny in (10, 20, 40)]
    errors = [abs(r / exact - 1) for r in rates]
    print(f"shear-mode decay rates {rates}, exact {exact:.5f}, rel. errors {errors}")
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.01


def test_yield_stress_decays_faster_and_energy_never_grows():
    viscous, _ = _decay_rate(_shear(500.0, 0.0, 20))
    plastic, r = _decay_rate(_shear(500.0, 5.0, 20))
    ke = r.series["kinetic_energy"]
    print(f"decay rate without / with yield stress: {viscous:.4f} / {plastic:.4f}")
    assert plastic > 1.05 * viscous
    assert np.all(np.diff(ke) <= 1e-12 * ke[0])


def test_stiff_bingham_runs_with_the_transport_time_step():
    base = ["domain.cells=[120,8]", "time.end=2.0", "output.every=1.0"]
    plain = run(case("inclined_dam_break", *base), write=False, comm=COMM)
    stiff = run(case("inclined_dam_break", *base,
                     "material.rheology={law: bingham, viscosity: 1.0e5, yield_stress: 0}"),
                write=False, comm=COMM)
    print(f"steps without rheology {plain.steps}, with mu = 1e5 Pa s {stiff.steps}")
    assert np.isfinite(stiff.h).all() and stiff.h.min() >= 0.0
    # Strang halves: the split step is at most twice as long, never shorter than transport's
    assert stiff.steps <= plain.steps
    assert abs(stiff.series["mass_error"][-1]) < 1e-12


@pytest.mark.parametrize("comm", [MPI.COMM_SELF])
def test_lake_at_rest_with_full_seed_parameters(comm):
    c = case("lake_at_rest", "material.friction={law: voellmy, phi_deg: 26, xi: 500}",
             "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}")
    result = run(c, write=False, comm=comm)
    for name, (e1, einf) in lake_errors(result).items():
        assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)
