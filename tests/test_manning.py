"""Manning friction (``law: manning``): the law, its input checks, and the sliding sheet.

Bounds come from the exact uniform-flow solution (``fem_runout/references/manning_sheet.py``):
the finest level of the ``manning_sheet`` ladder within 1 % in both methods, and a coarse
level within the physical bound stated in :func:`test_coarse_sheet_stays_below_its_uniform_flow`.
"""

import math

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.bench import ladders
from fem_runout.config import load_case
from fem_runout.config.schema import FrictionSpec
from fem_runout.errors import CaseError
from fem_runout.methods import method_names
from fem_runout.physics.friction import LAWS, Manning, Voellmy, friction_from_spec
from fem_runout.physics.slope import BedFrame
from fem_runout.references import manning_sheet as ref

COMM = MPI.COMM_SELF
G = 9.81
#: The ladder's levels (cells along the strip), coarse to fine.
LEVELS = (50, 100, 200, 400)


def _exact_rate(n, h, qx, qy, gt=G, h_n=None):
    """``r = -g_t n² |v| v / h_n^{1/3}`` (moving nodes)."""
    ux, uy = qx / h, qy / h
    coef = gt * n * n * np.hypot(ux, uy) / np.cbrt(h if h_n is None else h_n)
    return -coef * ux, -coef * uy


def _plane(count, theta):
    slope = math.tan(theta)
    cos = np.full(count, math.cos(theta))
    return BedFrame(np.tile([-slope, 0.0], (count, 1)), cos, G * cos)


# -- the law ------------------------------------------------------------------------------------


def test_manning_is_registered_and_built_from_the_case():
    assert "manning" in LAWS.names()
    law = friction_from_spec(FrictionSpec(law="manning", n=0.04), 9.8, 1e-5)
    assert isinstance(law, Manning) and not law.has_yield
    assert (law.n, law.gravity, law.dry_tol, law.mu) == (0.04, 9.8, 1e-5, 0.0)
    assert repr(law) == "Manning(n=0.04, g=9.8)"
    with pytest.raises(ValueError):
        Manning(0.0)


def test_rate_is_antiparallel_to_the_velocity_with_the_manning_magnitude():
    law = Manning(0.05, G)
    rng = np.random.default_rng(1)
    h = rng.uniform(0.05, 4.0, 200)
    qx, qy = rng.normal(0, 2, 200) * h, rng.normal(0, 2, 200) * h
    rx, ry = law.rate(h, qx, qy)
    ex, ey = _exact_rate(0.05, h, qx, qy)
    np.testing.assert_allclose(rx, ex, rtol=1e-13)
    np.testing.assert_allclose(ry, ey, rtol=1e-13)
    assert np.all(rx * qx + ry * qy < 0)
    np.testing.assert_allclose((rx * qy - ry * qx) / np.hypot(rx, ry) / np.hypot(qx, qy), 0.0,
                               atol=1e-14)
    # at rest and on dry nodes: no friction
    rx, ry = law.rate(np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    assert np.all(rx == 0.0) and np.all(ry == 0.0)


def test_rate_on_the_bed_uses_the_normal_thickness_and_the_speed_along_the_bed():
    """Down a 35° plane: ``g/cos²θ · n² u²/(h cosθ)^{1/3}`` on the horizontal momentum."""
    theta = math.radians(35.0)
    bed = _plane(3, theta)
    law = Manning(0.08, G)
    h, u = np.full(3, 1.5), np.array([1.0, 4.0, 9.0])
    rx, ry = law.rate(h, h * u, 0 * u, bed)
    ex, _ = _exact_rate(0.08, h, h * u, 0 * u, gt=G / math.cos(theta) ** 2,
                        h_n=h * math.cos(theta))
    np.testing.assert_allclose(rx, ex, rtol=1e-13)
    assert np.all(ry == 0.0)


@pytest.mark.parametrize("slope_form", [False, True])
def test_implicit_update_solves_the_stage_equation(slope_form):
    """``q - θ r(q) = q*`` to 1e-12, friction antiparallel, ``|q| < |q*|`` on every wet node."""
    rng = np.random.default_rng(5)
    count, n, theta = 2000, 0.06, 0.05
    h = rng.uniform(1e-3, 5.0, count)
    sx, sy = rng.normal(0, 1, count) * h, rng.normal(0, 1, count) * h
    bed = None
    gt, h_n = G, None
    if slope_form:  # motion along x on a plane sloping in x: s = 1/cosθ for n = ±x only
        bed, sy = _plane(count, math.radians(30.0)), 0.0 * sy
        gt, h_n = G / math.cos(math.radians(30.0)) ** 2, h * math.cos(math.radians(30.0))
    law = Manning(n, G)
    qx, qy = law.implicit_update(h, 0 * h, 0 * h, sx, sy, theta, bed)
    rx, ry = _exact_rate(n, h, qx, qy, gt, h_n)
    scale = np.hypot(sx, sy)
    res = np.hypot(qx - theta * rx - sx, qy - theta * ry - sy)
    assert np.max(res / scale) < 1e-12
    fx, fy = qx - sx, qy - sy  # θ r(q): along -q, so q keeps the direction of q*
    assert np.all(fx * qx + fy * qy < 0)
    assert np.max(np.abs(qx * sy - qy * sx) / (np.hypot(qx, qy) * scale)) < 1e-14
    assert np.all((np.hypot(qx, qy) < scale) & (np.hypot(qx, qy) > 0))


def test_manning_at_a_uniform_depth_is_voellmy_with_xi_from_n():
    """On one depth the drag coefficient ``n²/h^{1/3}`` is Voellmy's ``1/ξ`` (μ = 0)."""
    h = np.full(50, 2.0)
    rng = np.random.default_rng(2)
    sx, sy = rng.normal(0, 3, 50), rng.normal(0, 3, 50)
    n = 0.07
    a = Manning(n, G).implicit_update(h, sx, sy, sx, sy, 0.1)
    b = Voellmy(0.0, 2.0 ** (1 / 3) / n**2, G).implicit_update(h, sx, sy, sx, sy, 0.1)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12)


@pytest.mark.parametrize("slope", [1e-6, 1e-3, 0.1, 1.0])
def test_no_yield_a_layer_on_any_slope_starts_moving(slope):
    """No yield stress: one step of gravity from rest moves the layer, by the exact root."""
    law = Manning(0.1, G)
    assert not law.has_yield
    h, dt = np.array([0.01, 1.0, 5.0]), 0.05
    q_star = dt * G * slope * h
    qx, qy = law.implicit_update(h, 0 * h, 0 * h, q_star, 0 * h, dt)
    assert np.all(qx > 0) and np.all(qy == 0.0)
    a = dt * G * 0.01 / (np.cbrt(h) * h * h)  # q + a q² = q*
    np.testing.assert_allclose(qx, 2 * q_star / (1 + np.sqrt(1 + 4 * a * q_star)), rtol=1e-12)
    # the same on a bed, straight down
    bed = _plane(3, math.atan(slope))
    qx, _ = law.implicit_update(h, 0 * h, 0 * h, q_star, 0 * h, dt, bed)
    assert np.all(qx > 0)


def test_repeated_implicit_steps_reach_the_uniform_flow_speed():
    """Gravity explicit in halves, friction implicit: ``u → h^{2/3} S^{1/2}/n`` (0.5 %)."""
    s, n, h0 = 0.3, 0.05, 1.0
    law = Manning(n, G)
    dt = ref.relaxation_time(s, n, h0) / 200.0
    h, q = np.array([h0]), np.array([0.0])
    half = 0.5 * dt * G * s * h
    steps = 1200  # 6 relaxation times
    for _ in range(steps):
        q, _ = law.implicit_update(h, q, 0 * q, q + half, 0 * q, dt)
        q = q + half
    assert q[0] / h0 == pytest.approx(ref.speed(steps * dt, s, n, h0), rel=5e-3)
    assert q[0] / h0 == pytest.approx(ref.terminal_speed(s, n, h0), rel=5e-3)


# -- the references --------------------------------------------------------------------------


def test_reference_solves_its_ode_and_gives_manning_formula():
    t = np.linspace(0.0, 10.0, 2001)
    u = np.array([ref.speed(s) for s in t])
    a, b = G * ref.SLOPE, G * ref.N**2 / ref.H ** (4 / 3)
    np.testing.assert_allclose(np.gradient(u, t)[1:-1], (a - b * u * u)[1:-1], atol=2e-4)
    assert ref.terminal_speed(0.04, 0.1, 8.0) == pytest.approx(4.0 * 0.2 / 0.1)
    th = math.radians(ref.THETA)
    ua, ub = G * math.sin(th), G * ref.SLOPE_N**2 / ref.H_N ** (4 / 3)
    assert ref.slope_terminal_speed() == pytest.approx(math.sqrt(ua / ub), rel=1e-14)
    assert ref.slope_relaxation_time() == pytest.approx(1 / math.sqrt(ua * ub), rel=1e-14)


@pytest.mark.parametrize("method", method_names())
def test_finest_sheet_level_is_within_one_percent_of_uniform_flow(method):
    """Finest level of the ``manning_sheet`` ladder: speed within 1 % of the exact one."""
    level = ladders.manning_sheet(LEVELS[-1], method, COMM)
    print(method, level.level, level.error, level.extra)
    assert level.error <= 0.01
    assert level.extra["speed"] == pytest.approx(ref.terminal_speed(), rel=0.01)


@pytest.mark.parametrize("method", method_names())
def test_coarse_sheet_stays_below_its_uniform_flow(method):
    """Coarsest level: from rest the exact sheet never exceeds ``u_∞`` (the drag equals gravity
    there). A scheme may overshoot by at most one splitting step's gravity impulse
    ``g S Δt/2`` (TG2-PC's last half transport step, the Voellmy sheet's offset in
    docs/method.md), with the mean step ``Δt = t/steps``; and it must not lag by more than 5 %.
    """
    level = ladders.manning_sheet(LEVELS[0], method, COMM)
    speed, end = level.extra["speed"], ref.RELAXATIONS * ref.relaxation_time()
    impulse = G * ref.SLOPE * end / level.steps / 2.0
    print(method, speed, ref.terminal_speed(), impulse)
    assert 0.95 * level.extra["exact"] <= speed <= ref.terminal_speed() + impulse


@pytest.mark.parametrize("method", method_names())
def test_slope_form_sheet_reaches_the_speed_along_the_bed(method):
    """Slope form on 35°: ``U_∞ = h_n^{2/3} (sinθ)^{1/2}/n``; TG2-PC 1.2 %, DAMPM 1e-4 at 400."""
    level = ladders.manning_slope(400, method, COMM)
    print(method, level.error, level.extra)
    assert level.error <= 0.02


# -- input checks ------------------------------------------------------------------------------

GOOD = {
    "name": "m",
    "domain": {"extent": [0, 10, 0, 2], "cells": [5, 1]},
    "initial": {"depth": "1"},
    "time": {"end": 1.0},
}


@pytest.mark.parametrize(("friction", "message"), [
    ({"law": "manning"}, "case: material.friction.n: required for law 'manning'"),
    ({"law": "manning", "n": -1}, "case: material.friction.n: must be > 0, got -1"),
    ({"law": "manning", "n": 0}, "case: material.friction.n: must be > 0, got 0"),
    ({"law": "manning", "n": 0.03, "mu": 0.2},
     "case: material.friction.mu: not used by law 'manning'"),
    ({"law": "manning", "n": 0.03, "gamma": 0.1},
     "case: material.friction.gamma: not used by law 'manning'"),
    ({"law": "voellmy", "mu": 0.1, "xi": 200, "n": 0.03},
     "case: material.friction.n: not used by law 'voellmy' (only by 'manning')"),
    ({"law": "manning", "n": "rough"}, "case: material.friction.n: must be a number"),
])
def test_bad_manning_input_names_the_key(friction, message):
    with pytest.raises(CaseError) as info:
        load_case({**GOOD, "material": {"friction": friction}})
    assert str(info.value).startswith(message), str(info.value)


def test_manning_case_round_trips_without_gamma():
    case = load_case({**GOOD, "material": {"friction": {"law": "manning", "n": 0.03}}})
    friction = case.material.friction
    assert (friction.law, friction.n, friction.gamma, friction.mu_value) == (
        "manning", 0.03, None, None)
