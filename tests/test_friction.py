"""Bed friction (seed eq. 2): Coulomb stop, Voellmy terminal flow, per-node Newton, registry."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from fem_runout.config.schema import FrictionSpec
from fem_runout.physics.friction import (
    LAWS,
    Coulomb,
    FrictionLaw,
    Manning,
    Parameter,
    ParameterError,
    Voellmy,
    friction_from_spec,
    relaxed_sign,
)
from fem_runout.physics.friction.base import GAMMA_DEFAULT
from fem_runout.physics.friction.registry import Registry
from fem_runout.physics.slope import SlopeGeometry

G = 9.81


def _exact_rate(law, h, qx, qy):
    """``r(q)`` of seed eq. 2 with the exact sign (moving nodes only)."""
    ux, uy = qx / h, qy / h
    speed = np.hypot(ux, uy)
    coef = law.gravity * law.mu * h / speed + law.gravity * law.inv_xi * speed
    return -coef * ux, -coef * uy


def _step(law, h, q, slope, dt):
    """Gravity along x explicit, friction implicit with θ = dt; returns the new q_x."""
    q_star = q + dt * G * slope * h
    qx, _ = law.implicit_update(h, q, 0.0 * q, q_star, 0.0 * q, dt)
    return qx


def test_layer_below_yield_stays_exactly_at_rest():
    law = Coulomb(mu=0.3, gravity=G)
    h = np.array([0.5, 1.0, 2.0, 3.0])
    dt, slope = 0.01, 0.1
    direction = np.array([1.0, -0.3]) / math.hypot(1.0, -0.3)
    q_star = dt * G * slope * h
    qx, qy = law.implicit_update(h, 0 * h, 0 * h, q_star * direction[0], q_star * direction[1], dt)
    assert np.all(qx == 0.0) and np.all(qy == 0.0)
    # exactly at the yield: still at rest
    qx, qy = law.implicit_update(h, 0 * h, 0 * h, dt * G * 0.3 * h, 0 * h, dt)
    assert np.all(qx == 0.0) and np.all(qy == 0.0)


def test_sliding_layer_decelerates_stops_and_stays_stopped():
    law = Coulomb(mu=0.3, gravity=G)
    h = np.array([1.0])
    dt, slope, u0 = 0.01, 0.1, 5.0
    q = np.array([u0])
    t, t_stop, speeds = 0.0, None, []
    for _ in range(1500):
        q = _step(law, h, q, slope, dt)
        t += dt
        if t_stop is None and q[0] == 0.0:
            t_stop = t
        if t_stop is not None:
            speeds.append(q[0] / h[0])
        elif t < 2.0:  # constant deceleration g (μ - S) while sliding
            assert q[0] == pytest.approx(u0 - G * (0.3 - slope) * t, abs=1e-9)
    expected = u0 / (G * (0.3 - slope))
    assert t_stop is not None
    assert abs(t_stop - expected) / expected < 0.02
    assert len(speeds) > 1000
    assert np.max(np.abs(speeds)) <= 1e-12  # no creep, no reversal


def test_voellmy_sheet_flow_reaches_terminal_speed():
    mu, xi, slope, h0 = 0.2, 500.0, 0.5, 1.0
    law = Voellmy(mu=mu, xi=xi, gravity=G)
    a, b = G * (slope - mu), G / (xi * h0)
    relax = 1.0 / math.sqrt(a * b)
    dt = relax / 200.0
    h = np.array([h0])
    q = np.array([0.0])
    half = 0.5 * dt * G * slope * h
    n = 600
    for _ in range(n):  # Strang-like: gravity dt/2, friction (implicit) dt, gravity dt/2
        q_star = q + half
        q, _ = law.implicit_update(h, q, 0 * q, q_star, 0 * q, dt)
        q = q + half
    t = n * dt
    exact = math.sqrt(a / b) * math.tanh(math.sqrt(a * b) * t)
    assert abs(q[0] / h0 - exact) / exact < 0.005


@pytest.mark.parametrize("xi", [math.inf, 1000.0, 50.0, 1.0])
def test_newton_solves_the_stage_equation_with_antiparallel_friction(xi):
    rng = np.random.default_rng(7)
    n = 2000
    law = Coulomb(0.35, G) if math.isinf(xi) else Voellmy(0.35, xi, G)
    h = rng.uniform(1e-3, 5.0, n)
    qx_star = rng.normal(0, 0.1, n) * h
    qy_star = rng.normal(0, 0.1, n) * h
    theta = 0.02
    qx, qy = law.implicit_update(h, qx_star, qy_star, qx_star, qy_star, theta)
    moving = np.hypot(qx_star, qy_star) > theta * G * law.mu * h
    assert moving.sum() > n // 4 and (~moving).sum() > 10
    assert np.all(qx[~moving] == 0.0) and np.all(qy[~moving] == 0.0)
    rx, ry = _exact_rate(law, h[moving], qx[moving], qy[moving])
    scale = np.hypot(qx_star, qy_star)[moving]
    res = np.hypot(
        qx[moving] - theta * rx - qx_star[moving], qy[moving] - theta * ry - qy_star[moving]
    )
    assert np.max(res / scale) < 1e-12
    # friction (q - q*)/θ is antiparallel to v: no sideways component, |q| < |q*|
    fx, fy = qx - qx_star, qy - qy_star
    cross = fx * qy - fy * qx
    assert np.max(np.abs(cross[moving]) / (np.hypot(fx, fy) * np.hypot(qx, qy))[moving]) < 1e-12
    assert np.all((fx * qx + fy * qy)[moving] < 0)
    assert np.all(np.hypot(qx, qy)[moving] < scale)


def test_newton_result_does_not_depend_on_the_initial_guess():
    law = Voellmy(0.2, 200.0, G)
    rng = np.random.default_rng(3)
    h = rng.uniform(0.01, 2.0, 500)
    sx, sy = rng.normal(0, 5, 500), rng.normal(0, 5, 500)
    a = law.implicit_update(h, sx, sy, sx, sy, 0.05)
    b = law.implicit_update(h, 0 * sx, 0 * sy, sx, sy, 0.05)
    c = law.implicit_update(h, -sx, 3 * sy, sx, sy, 0.05)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-15)
    for x, y in zip(a, c, strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-15)


def test_pure_coulomb_update_is_the_exact_deceleration():
    law = Coulomb(0.3, G)
    h = np.array([1.0, 2.0])
    qx_star, qy_star = np.array([3.0, 0.0]), np.array([4.0, -1.0])
    qx, qy = law.implicit_update(h, qx_star, qy_star, qx_star, qy_star, 0.1)
    impulse = 0.1 * G * 0.3 * h
    norm = np.hypot(qx_star, qy_star)
    np.testing.assert_allclose(np.hypot(qx, qy), norm - impulse, rtol=1e-14)


def test_dry_nodes_and_zero_theta():
    law = Voellmy(0.3, 400.0, G, dry_tol=1e-6)
    h = np.array([0.0, 1e-7, 1.0])
    q = np.array([1.0, 1.0, 1.0])
    qx, qy = law.implicit_update(h, q, q, q, q, 0.1)
    assert qx[0] == qx[1] == qy[0] == qy[1] == 0.0
    assert 0.0 < qx[2] < 1.0
    rx, ry = law.rate(h, q, q)
    assert rx[0] == rx[1] == 0.0
    qx, qy = law.implicit_update(h[2:], q[2:], q[2:], q[2:], q[2:], 0.0)
    assert qx[0] == qy[0] == 1.0


def test_rate_magnitude_direction_and_relaxed_sign():
    law = Voellmy(0.3, 400.0, G, gamma=1e-2)
    h = np.full(4, 2.0)
    ux = np.array([3.0, 0.0, 0.004, 0.0])
    uy = np.array([4.0, -2.0, 0.003, 0.0])
    rx, ry = law.rate(h, h * ux, h * uy)
    speed = np.hypot(ux, uy)
    expected = G * 0.3 * h * relaxed_sign(speed, 1e-2) + G * speed**2 / 400.0
    np.testing.assert_allclose(np.hypot(rx, ry), expected, rtol=1e-14)
    assert rx[3] == ry[3] == 0.0
    np.testing.assert_allclose((rx * uy - ry * ux)[:3], 0.0, atol=1e-14)
    assert np.all((rx * ux + ry * uy)[:3] < 0)
    # the relaxed Coulomb part is linear below γ: -g μ h v/γ
    assert rx[2] == pytest.approx(-G * 0.3 * 2.0 * 0.004 / 1e-2 - G * speed[2] * 0.004 / 400)


def test_implicit_update_is_consistent_with_the_rate():
    law = Voellmy(0.25, 300.0, G)
    h = np.array([0.7, 1.5])
    qx, qy = np.array([2.0, -1.0]), np.array([1.0, 3.0])
    theta = 1e-7
    rx, ry = law.rate(h, qx, qy)
    nx, ny = law.implicit_update(h, qx, qy, qx, qy, theta)
    np.testing.assert_allclose((nx - qx) / theta, rx, rtol=1e-5)
    np.testing.assert_allclose((ny - qy) / theta, ry, rtol=1e-5)


def test_relaxed_sign_of_eq20():
    s = np.array([-1.0, -0.01, -0.005, 0.0, 0.005, 0.02])
    np.testing.assert_allclose(relaxed_sign(s, 0.01), [-1, -1, -0.5, 0, 0.5, 1])


def test_friction_from_spec():
    assert friction_from_spec(FrictionSpec(), G) is None
    law = friction_from_spec(FrictionSpec(law="coulomb", phi_deg=30.0), G)
    assert isinstance(law, Coulomb) and law.inv_xi == 0.0 and math.isinf(law.xi)
    assert law.mu == pytest.approx(math.tan(math.radians(30.0)))
    assert law.gamma == 1e-2
    law = friction_from_spec(FrictionSpec(law="voellmy", mu=0.2, xi=500.0, gamma=1e-3), 9.8)
    assert isinstance(law, Voellmy)
    assert (law.mu, law.xi, law.gamma, law.gravity) == (0.2, 500.0, 1e-3, 9.8)
    with pytest.raises(ValueError):
        Voellmy(0.2, 0.0)


# -- the registry -----------------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]


def test_registry_gives_the_schema_its_laws_and_keys():
    assert LAWS.names() == ("coulomb", "voellmy", "manning")
    assert list(FrictionSpec.model_fields) == ["law", "mu", "phi_deg", "xi", "n", "gamma"]
    assert LAWS.users("mu") == ("coulomb", "voellmy") and LAWS.users("n") == ("manning",)
    for law in LAWS:
        assert issubclass(law, FrictionLaw) and law.name in LAWS


def test_gamma_default_is_written_once_and_filled_for_the_laws_that_take_it():
    sources = [*sorted((ROOT / "fem_runout/physics/friction").glob("*.py")),
               ROOT / "fem_runout/config/schema.py"]
    hits = [p.name for p in sources for line in p.read_text().splitlines()
            if re.search(r"\b(1e-2|1\.0e-2|0\.01)\b", line)]
    assert hits == ["base.py"]
    assert FrictionSpec(law="coulomb", mu=0.1).gamma == GAMMA_DEFAULT == Coulomb(0.1).gamma
    assert FrictionSpec(law="voellmy", mu=0.1, xi=9.0).gamma == Voellmy(0.1, 9.0).gamma
    assert FrictionSpec(law="manning", n=0.1).gamma is None


class _LinearDrag(FrictionLaw):
    """A toy law for the registry: ``k = c/h`` (not registered in LAWS)."""

    name = "linear"
    parameters = (Parameter("c", "drag", "m/s", gt=0.0, required=True),
                  Parameter("mu", "friction coefficient", ge=0.0))

    def __init__(self, c, gravity=G):
        super().__init__(0.0, gravity)
        self.c = c

    def drag_coefficient(self, h, bed):
        return self.c / h


def test_a_new_law_needs_only_its_class_and_one_registration():
    reg = Registry("friction law")
    reg.register(Coulomb)
    reg.register(_LinearDrag)
    assert reg.names() == ("coulomb", "linear")
    assert [p.name for p in reg.parameters()] == ["mu", "phi_deg", "c", "gamma"]
    reg.check("linear", {"c": 2.0})
    with pytest.raises(ParameterError, match="required for law 'linear'") as info:
        reg.check("linear", {})
    assert info.value.key == "c"
    with pytest.raises(ParameterError, match="not used by law 'coulomb'") as info:
        reg.check("coulomb", {"mu": 0.1, "c": 1.0})
    assert info.value.key == "c"
    with pytest.raises(ParameterError, match="exactly one of mu or phi_deg"):
        reg.check("coulomb", {"mu": 0.1, "phi_deg": 3.0})
    assert reg.with_defaults("coulomb", {"mu": 0.1}) == {"mu": 0.1, "gamma": GAMMA_DEFAULT}
    with pytest.raises(ValueError, match="already taken"):
        reg.register(_LinearDrag)
    clash = type("Clash", (_LinearDrag,), {"name": "clash",
                                           "parameters": (Parameter("mu", "other", ge=1.0),)})
    with pytest.raises(ValueError, match="clashes"):
        reg.register(clash)
    # the shared Newton update works for it: q + θ g (c/h) |q| q/h² = q*
    law = _LinearDrag(0.5)
    h, star = np.array([2.0]), np.array([3.0])
    qx, _ = law.implicit_update(h, star, 0 * star, star, 0 * star, 0.1)
    assert qx[0] + 0.1 * G * 0.25 * qx[0] ** 2 / 4.0 == pytest.approx(3.0, rel=1e-13)


def test_every_law_and_key_is_documented_in_the_case_schema():
    text = (ROOT / "docs/case_schema.md").read_text()
    table = text[text.index("`material.friction`:"):text.index("`material.rheology`:")]
    for law in LAWS:
        assert f"`{law.name}`" in table
        for p in law.parameters:
            assert f"| `{p.name}` |" in table


@pytest.mark.parametrize("law", [Voellmy(0.2, 500.0), Coulomb(0.3), Manning(0.05)])
def test_only_wet_nodes_are_solved_and_the_bits_do_not_change(law):
    """The update works on the wet nodes only; each node's result is that of a solve alone."""
    rng = np.random.default_rng(7)
    n = 400
    h = np.where(rng.random(n) < 0.7, 0.0, rng.random(n) * 2.0)
    h[::37] = 0.5 * law.dry_tol  # wet by a hair's breadth less than the dry tolerance
    sx, sy = rng.normal(size=n) * h * 3.0, rng.normal(size=n) * h * 3.0
    qx, qy = law.implicit_update(h, sx, sy, sx, sy, 0.05)
    wet = h > law.dry_tol
    assert np.all(qx[~wet] == 0.0) and np.all(qy[~wet] == 0.0)
    for i in np.flatnonzero(wet)[:40]:
        one = law.implicit_update(h[i:i + 1], sx[i:i + 1], sy[i:i + 1], sx[i:i + 1],
                                  sy[i:i + 1], 0.05)
        assert one[0][0] == qx[i] and one[1][0] == qy[i]


# -- the step integrator (FrictionLaw.integrate, Alexander's SDIRK) ---------------------------
def test_integrate_is_exact_for_coulomb_stop_and_deceleration():
    """Constant deceleration g μ: stop iff |q| <= dt g μ h, else |q| - dt g μ h, direction kept."""
    law = Coulomb(mu=0.3, gravity=G)
    dt, h = 0.1, np.full(7, 2.0)
    cap = dt * G * 0.3 * 2.0
    mag = cap * np.array([0.0, 0.3, 0.707, 0.8, 1.0, 1.2, 5.0])
    direction = np.array([0.6, -0.8])
    qx, qy = law.integrate(h, mag * direction[0], mag * direction[1], dt)
    expect = np.maximum(mag - cap, 0.0)
    assert np.allclose(np.hypot(qx, qy), expect, rtol=0, atol=1e-13 * cap)
    moving = expect > 0
    assert np.allclose(qx[moving] / np.hypot(qx, qy)[moving], 0.6, atol=1e-14)
    assert np.all(qx[~moving] == 0.0) and np.all(qy[~moving] == 0.0)


def test_integrate_is_second_order_for_the_drag():
    """Voellmy drag alone: du/dt = -g u²/(ξ h), u = u0/(1 + g u0 t/(ξ h)); order 2 over a run."""
    xi, h, u0, end = 200.0, 0.5, 20.0, 4.0
    law = Voellmy(0.0, xi, G)
    exact = u0 / (1.0 + G * u0 * end / (xi * h))
    errors = []
    for n in (10, 20, 40, 80):
        q = np.array([h * u0])
        for _ in range(n):
            q, _ = law.integrate(np.array([h]), q, 0 * q, end / n)
        errors.append(abs(q[0] / h - exact) / exact)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.9), orders
    assert errors[0] < 0.1 * abs(_backward_euler_error(law, h, u0, end, 10, exact))


def _backward_euler_error(law, h, u0, end, n, exact):
    q = np.array([h * u0])
    for _ in range(n):
        q, _ = law.implicit_update(np.array([h]), q, 0 * q, q, 0 * q, end / n)
    return (q[0] / h - exact) / exact


def test_integrate_is_continuous_at_the_stop():
    """Around the Coulomb stop (|q| = dt g μ h) the result is continuous: no jump at the switch."""
    law = Voellmy(0.2, 500.0, G)
    dt, h = 0.05, np.array([1.0])
    cap = dt * G * 0.2
    qs = cap * (1.0 + np.linspace(-1e-3, 1e-3, 201))
    out = np.array([law.integrate(h, np.array([q]), np.array([0.0]), dt)[0][0] for q in qs])
    assert np.all(np.abs(np.diff(out)) <= 2.0 * np.diff(qs).max())
    assert np.all(out >= 0.0) and np.all(np.diff(out) >= 0.0)


@pytest.mark.parametrize("law", [Voellmy(0.155, 4000.0, G), Voellmy(0.3, 200.0, G, dry_tol=1e-5),
                                 Manning(0.05, G), Coulomb(mu=0.4, gravity=G)],
                         ids=["voellmy", "voellmy-dry", "manning", "coulomb"])
def test_integrate_in_one_pass_has_the_bits_of_its_two_stages(law):
    """The compiled step equals the two numpy stage solves bit for bit: dry, thin and deep
    nodes, at rest and moving, on the seed's horizontal form and on a curved bed."""
    rng = np.random.default_rng(11)
    n = 5000
    h = 10.0 ** rng.uniform(-7, 1, n)
    h[::7], h[::11] = 0.0, law.dry_tol
    qx, qy = rng.normal(size=n) * h * 5.0, rng.normal(size=n) * h * 5.0
    qx[::13], qy[::17] = 0.0, 0.0
    geometry = SlopeGeometry(rng.normal(size=(n, 2)) * 0.5, rng.normal(size=(n, 3)) * 0.01, G,
                             curvature=True)
    u = qx / np.where(h > 0, h, 1.0), qy / np.where(h > 0, h, 1.0)
    moving = []
    for bed in (None, geometry.frame(), geometry.frame(*u)):
        for dt in (0.01, 0.3, 3.0):
            one = law.integrate(h, qx, qy, dt, bed)
            two = law.integrate_in_stages(h, qx, qy, dt, bed)
            assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
            moving.append(np.count_nonzero(one[0]))
    assert max(moving) > n // 4 and min(moving) < max(moving) // 2  # moving and stopping
