"""Depth-integrated Bingham rheology (seed eqs. 3-7)."""

import numpy as np
import pytest

from fem_runout.config import load_case
from fem_runout.config.schema import RheologySpec
from fem_runout.errors import CaseError
from fem_runout.physics.rheology import (
    RHEOLOGIES,
    Bingham,
    Rheology,
    plug_ratio,
    register_rheology,
    rheology_from_spec,
    strain_rate,
)


def _eq7(psi, a):
    return 48.0 * psi**2 - (114.0 + 32.0 * a) * psi + 65.0


def test_plug_ratio_is_the_root_of_eq7_in_unit_interval():
    speed = np.array([0.0, 1e-6, 1e-3, 0.1, 1.0, 10.0, 1e3])
    h = np.full(speed.size, 0.5)
    mu, tau = 20.0, 300.0
    psi = plug_ratio(speed, h, mu, tau)
    a = 6.0 * mu * speed / (tau * h)
    assert np.all((psi >= 0.0) & (psi <= 1.0))
    np.testing.assert_allclose(_eq7(psi, a), 0.0, atol=1e-11 * (114 + 32 * a).max())
    # the other root is > 1; ψ decreases from 0.951 (plug) with a
    other = 65.0 / (48.0 * psi)
    assert np.all(other > 1.0)
    assert psi[0] == pytest.approx(130.0 / (114.0 + np.sqrt(114.0**2 - 12480.0)), rel=1e-14)
    assert np.all(np.diff(psi) < 0)


def test_plug_ratio_newtonian_is_zero():
    psi = plug_ratio(np.array([0.0, 1.0]), np.array([1.0, 1.0]), 10.0, 0.0)
    assert np.all(psi == 0.0)


def _simple_shear(n, amplitude, k, y, u_node=0.0):
    """u = U sin(k y) (plus a node velocity), v = 0: ∂y u = U k cos(k y)."""
    grad = np.zeros((n, 2, 2))
    grad[:, 0, 1] = amplitude * k * np.cos(k * y)
    return np.full(n, u_node), np.zeros(n), grad


def test_newtonian_limit_gives_sigma_xy_equal_mu_dyu():
    mu = 35.0
    law = Bingham(viscosity=mu, yield_stress=0.0, density=2000.0)
    y = np.linspace(0.0, 3.0, 7)
    u, v, grad = _simple_shear(y.size, 0.7, 2.0, y, u_node=1.3)
    h = np.full(y.size, 0.8)
    np.testing.assert_allclose(law.effective_viscosity(h, u, v, grad), mu, rtol=1e-15)
    sigma = law.stress(h, u, v, grad)
    np.testing.assert_allclose(sigma[:, 0, 1], mu * grad[:, 0, 1], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(sigma[:, 0, 0], 0.0, atol=1e-14)
    np.testing.assert_allclose(law.kinematic_stress(h, u, v, grad), sigma / 2000.0)


def test_bingham_simple_shear_adds_the_yield_stress():
    mu, tau = 10.0, 500.0
    law = Bingham(mu, tau, 1800.0, reg=1e-3)
    rate = np.array([1.0, 5.0, 50.0])
    u, v, grad = _simple_shear(3, 1.0, 1.0, np.zeros(3))
    grad[:, 0, 1] = rate  # u = 0 at the node: no vertical shear
    sigma = law.stress(np.ones(3), u, v, grad)
    expected = mu * rate + tau * rate / (2.0 * np.sqrt(rate**2 / 4.0 + 1e-6))
    np.testing.assert_allclose(sigma[:, 0, 1], expected, rtol=1e-14)
    np.testing.assert_allclose(sigma[:, 0, 1], mu * rate + tau, rtol=1e-5)


def test_effective_viscosity_is_finite_at_zero_strain_and_grows_with_yield_stress():
    h = np.array([1.0, 0.5])
    u, v, grad = np.zeros(2), np.zeros(2), np.zeros((2, 2, 2))
    law = Bingham(12.0, 100.0, 2000.0, reg=1e-3)
    mu_eff = law.effective_viscosity(h, u, v, grad)
    np.testing.assert_allclose(mu_eff, 12.0 + 100.0 / (2.0 * 1e-3))
    assert law.max_effective_viscosity(h, u, v, grad) == pytest.approx(12.0 + 5e4)
    rng = np.random.default_rng(1)
    grad = rng.normal(size=(50, 2, 2))
    h, u, v = rng.uniform(0.1, 2, 50), rng.normal(size=50), rng.normal(size=50)
    values = [Bingham(12.0, tau, 2000.0).effective_viscosity(h, u, v, grad) for tau in (0, 10, 100)]
    assert np.all(values[0] < values[1]) and np.all(values[1] < values[2])


def test_stress_is_symmetric_and_proportional_to_strain_rate():
    rng = np.random.default_rng(2)
    n = 40
    grad = rng.normal(size=(n, 2, 2))
    h, u, v = rng.uniform(0.1, 2, n), rng.normal(size=n), rng.normal(size=n)
    law = Bingham(5.0, 200.0, 2000.0)
    sigma = law.stress(h, u, v, grad)
    np.testing.assert_allclose(sigma, np.swapaxes(sigma, 1, 2), rtol=0, atol=0)
    mu_eff = law.effective_viscosity(h, u, v, grad)
    np.testing.assert_allclose(sigma, 2 * mu_eff[:, None, None] * strain_rate(grad), rtol=1e-15)
    np.testing.assert_allclose(sigma[:, 0, 1], mu_eff * (grad[:, 0, 1] + grad[:, 1, 0]))


def test_second_invariant_includes_vertical_shear_of_eq6():
    mu, tau = 10.0, 400.0
    law = Bingham(mu, tau, 2000.0)
    h, u, v = np.array([0.5]), np.array([2.0]), np.array([-1.0])
    grad = np.array([[[0.3, 0.1], [-0.2, 0.4]]])
    psi = plug_ratio(np.hypot(u, v), h, mu, tau)
    dzu, dzv = 3 / (2 + psi) * u / h, 3 / (2 + psi) * v / h
    d = strain_rate(grad)[0]
    dbar = np.array(
        [
            [d[0, 0], d[0, 1], dzu[0] / 2],
            [d[1, 0], d[1, 1], dzv[0] / 2],
            [dzu[0] / 2, dzv[0] / 2, -(d[0, 0] + d[1, 1])],
        ]
    )
    i2 = law.second_invariant(h, u, v, grad)
    assert i2[0] == pytest.approx(0.5 * np.sum(dbar * dbar), rel=1e-14)
    # dry node: no vertical shear
    dry = law.second_invariant(np.array([0.0]), u, v, grad)
    assert dry[0] == pytest.approx(0.5 * np.sum(dbar[:2, :2] ** 2) + 0.5 * dbar[2, 2] ** 2)


def test_rheology_from_spec():
    assert rheology_from_spec(RheologySpec(), 2000.0) is None
    law = rheology_from_spec(RheologySpec(law="bingham", viscosity=3.0, yield_stress=40.0), 1900.0)
    assert isinstance(law, Bingham)
    assert (law.viscosity, law.yield_stress, law.density, law.reg) == (3.0, 40.0, 1900.0, 1e-3)
    with pytest.raises(ValueError):
        Bingham(1.0, 1.0, 0.0)


def test_rheology_registry_names_bingham_and_its_keys():
    assert RHEOLOGIES.names() == ("bingham",)
    assert [p.name for p in RHEOLOGIES.parameters()] == ["viscosity", "yield_stress"]
    assert list(RheologySpec.model_fields) == ["law", "viscosity", "yield_stress"]
    assert isinstance(Bingham(1.0, 2.0, 1000.0), Rheology)
    law = rheology_from_spec(RheologySpec(law="bingham", viscosity=3.0, yield_stress=4.0), 1e3,
                             reg=0.5)
    assert law.reg == 0.5
    with pytest.raises(ValueError, match="already taken"):
        register_rheology(Bingham)


@pytest.mark.parametrize(("rheology", "message"), [
    ({"law": "bingham", "viscosity": 1},
     "case: material.rheology.yield_stress: required for law 'bingham'"),
    ({"law": "bingham", "viscosity": -1, "yield_stress": 1},
     "case: material.rheology.viscosity: must be >= 0, got -1"),
    ({"law": "none", "yield_stress": 1},
     "case: material.rheology.yield_stress: not allowed with law 'none'"),
    ({"law": "herschel"}, "case: material.rheology.law: 'herschel' is not a known law; "
                          "allowed: none, bingham"),
    ({"law": "bingham", "viscosity": 1, "yield_stress": 1, "n": 2},
     "case: material.rheology.n: unknown key; allowed keys: law, viscosity, yield_stress"),
])
def test_bad_rheology_input_names_the_key(rheology, message):
    case = {"name": "r", "domain": {"extent": [0, 1, 0, 1], "cells": [2, 2]},
            "initial": {"depth": "1"}, "time": {"end": 1.0}, "material": {"rheology": rheology}}
    with pytest.raises(CaseError) as info:
        load_case(case)
    assert str(info.value).startswith(message), str(info.value)
