"""IMEX-RKC (seed eqs. 17-19): coefficients, stability, stage count, orders, stiff problems."""

import math

import numpy as np
import pytest

from fem_runout.integrators.rkc import (
    IMEXRKC,
    rkc_coefficients,
    spectral_radius_power,
    stability_polynomial,
    stages,
)
from fem_runout.physics.friction import Coulomb


def _grid(n):
    """Interior nodes of [0, π] with n cells, and the central-difference Laplacian (Dirichlet)."""
    x = np.linspace(0.0, np.pi, n + 1)[1:-1]
    dx = x[1] - x[0]

    def lap(w):
        out = -2.0 * w
        out[1:] += w[:-1]
        out[:-1] += w[1:]
        return out / dx**2

    return x, dx, lap


def _matrix(n):
    x, dx, _ = _grid(n)
    k = x.size
    return (np.diag(-2 * np.ones(k)) + np.diag(np.ones(k - 1), 1) + np.diag(np.ones(k - 1), -1)) / (
        dx**2
    )


def _sigma_for(m, dt):
    """A spectral radius for which seed eq. 18 gives exactly m stages."""
    return 0.0 if m == 2 else 0.999 * 0.653 * ((m - 1) ** 2 - 1) / dt


def _order(errors):
    """Least-squares slope of log2(error) against the refinement level (dt halved each time)."""
    levels = np.arange(len(errors))
    return -np.polyfit(levels, np.log2(errors), 1)[0]


def _linear_run(scheme, n_steps, u0, lap, k, sigma):
    """Integrate u' = lap(u) - k u to t = 1 (k scalar or per node)."""
    dt = 1.0 / n_steps
    u = u0.copy()
    for _ in range(n_steps):
        u = scheme.step(
            u,
            dt,
            sigma(dt),
            lap,
            lambda rhs, theta: rhs / (1.0 + theta * k),
            lambda w: -k * w,
        )
    return u


@pytest.mark.parametrize("m", [2, 3, 5, 10, 50, 200])
def test_coefficients(m):
    co = rkc_coefficients(m)
    assert co.m == m and co.omega0 == pytest.approx(1 + (2 / 13) / m**2, rel=1e-15)
    assert co.c[0] == 0.0 and co.c[m] == pytest.approx(1.0, rel=1e-11)
    assert np.all(np.diff(co.c) >= -1e-14)  # non-decreasing; c_1 = c_2 = μ̃_1 (b_1 = 1/ω0)
    assert co.c[1] == co.mu_t[1] == pytest.approx(co.omega1 / co.omega0, rel=1e-15)
    # consistency of the implicit part: μ_j μ̃_1 = μ̃_j
    np.testing.assert_allclose(co.mu[2:] * co.mu_t[1], co.mu_t[2:], rtol=1e-13)
    # c_j = T'_m T''_j / (T''_m T'_j) for j >= 2 (RKC, Sommeijer et al. 1997)
    x, t_prev, t = co.omega0, 1.0, co.omega0
    dt_prev, dt_cur, d2_prev, d2_cur = 0.0, 1.0, 0.0, 0.0
    for j in range(2, m + 1):
        d2_prev, d2_cur = d2_cur, 4 * dt_cur + 2 * x * d2_cur - d2_prev
        dt_prev, dt_cur = dt_cur, 2 * t + 2 * x * dt_cur - dt_prev
        t_prev, t = t, 2 * x * t - t_prev
        assert co.c[j] == pytest.approx(co.omega1 * d2_cur / dt_cur, rel=1e-10)
    with pytest.raises(ValueError):
        co.mu[0] = 1.0


@pytest.mark.parametrize("m", [2, 3, 4, 7, 16, 40])
def test_stability_polynomial_is_bounded_on_minus_beta_zero(m):
    co = rkc_coefficients(m)
    z = np.linspace(-co.beta, 0.0, 20001)
    p = stability_polynomial(m, z)
    assert np.max(np.abs(p)) <= 1.0 + 1e-12
    assert co.beta == pytest.approx(0.653 * (m * m - 1), rel=0.02)
    # second order: P(z) = 1 + z + z²/2 + O(z³)
    for h in (1e-2, 1e-3):
        assert abs(stability_polynomial(m, -h) - (1 - h + h * h / 2)) < m**4 * h**3
    # with F_R = 0 the step is the RKC polynomial
    lam = -0.5 * co.beta / 0.1
    scheme = IMEXRKC()
    w = scheme.step(
        np.ones(1), 0.1, _sigma_for(m, 0.1), lambda w: lam * w, lambda r, t: r, lambda w: 0 * w
    )
    assert scheme.last_stages == m
    assert w[0] == pytest.approx(float(stability_polynomial(m, -0.5 * co.beta)), rel=1e-12)


def test_stage_count_of_eq18():
    assert stages(0.1, 0.0) == 2
    assert stages(0.0, 1e9) == 2
    for x in (0.1, 1.0, 3.0, 10.0, 100.0, 1e4):
        m = stages(1.0, x)
        assert m == 1 + math.ceil(math.sqrt(1 + x / 0.653))
        assert x <= rkc_coefficients(m).beta  # stable
    assert stages(1.0, 1e4) == 125
    assert [stages(1.0, x) for x in (1, 10, 100, 1000)] == sorted(
        stages(1.0, x) for x in (1, 10, 100, 1000)
    )
    with pytest.raises(ValueError):
        stages(-1.0, 1.0)
    with pytest.raises(ValueError):
        rkc_coefficients(1)


@pytest.mark.parametrize("m", [2, 3, 6, 20])
@pytest.mark.parametrize("lam_d, lam_r", [(-3.0, -1.0), (-50.0, -1e4), (0.0, -7.0), (-20, 0.0)])
def test_seed_scheme_is_rkc_in_zeta(m, lam_d, lam_r):
    """w_{n+1} = P_m(ζ) w_n, ζ = Δt(λ_D + λ_R)/(1 - μ̃_1 Δt λ_R): stable for any λ_R <= 0."""
    dt = 0.05
    sigma = _sigma_for(m, dt)
    scheme = IMEXRKC()
    w = scheme.step(
        np.array([2.0]),
        dt,
        sigma,
        lambda w: lam_d * w,
        lambda r, theta: r / (1 - theta * lam_r),
        lambda w: lam_r * w,
    )
    assert scheme.last_stages == m
    theta = rkc_coefficients(m).mu_t[1] * dt
    zeta = dt * (lam_d + lam_r) / (1 - theta * lam_r)
    if -dt * lam_d <= rkc_coefficients(m).beta:  # λ_D in the stability interval
        assert abs(w[0]) <= 2.0
    assert w[0] == pytest.approx(2.0 * float(stability_polynomial(m, zeta)), rel=1e-11, abs=1e-14)


@pytest.mark.parametrize("second_order_reaction", [False, True])
def test_diffusion_is_second_order(second_order_reaction):
    x, dx, lap = _grid(40)
    lam = 4 / dx**2 * np.sin(dx / 2) ** 2  # eigenvalue of sin x for the discrete Laplacian
    scheme = IMEXRKC(second_order_reaction)
    errors = []
    for n in (5, 10, 20, 40):  # σ_J = 4/dx², m from eq. 18 (16, 12, 9, 7 stages)
        u = _linear_run(scheme, n, np.sin(x), lap, 0.0, lambda dt: 4 / dx**2)
        errors.append(np.max(np.abs(u - math.exp(-lam) * np.sin(x))))
    assert _order(errors) >= 1.9
    assert errors[-1] < 2e-5


def test_heat_equation_with_reaction_is_second_order():
    """u_t = u_xx - k u, u = e^{-(1+k)t} sin x (semi-discrete: e^{-(λ_h+k)t} sin x_i)."""
    x, dx, lap = _grid(40)
    k = 1.0
    lam = 4 / dx**2 * np.sin(dx / 2) ** 2
    exact = math.exp(-(lam + k)) * np.sin(x)
    assert np.max(np.abs(exact - math.exp(-(1 + k)) * np.sin(x))) < 1e-4
    scheme = IMEXRKC(second_order_reaction=True)
    errors = [
        np.max(np.abs(_linear_run(scheme, n, np.sin(x), lap, k, lambda dt: 4 / dx**2) - exact))
        for n in (5, 10, 20, 40)
    ]
    orders = -np.diff(np.log2(errors))
    assert np.all(orders >= 1.9), orders


@pytest.mark.parametrize(
    "m, cells, levels",
    [(2, 10, (40, 80, 160, 320)), (5, 40, (80, 160, 320, 640)), (12, 40, (20, 40, 80, 160))],
)
def test_reaction_order_at_fixed_stage_count(m, cells, levels):
    """Non-commuting F_D, F_R (k varies in x): seed scheme first order, corrected second order."""
    x, dx, lap = _grid(cells)
    assert 4 / dx**2 / levels[0] <= rkc_coefficients(m).beta  # stable at every level
    k = 2.0 + 1.5 * np.cos(3 * x)
    vals, vecs = np.linalg.eigh(_matrix(cells) - np.diag(k))
    u0 = np.sin(x) + 0.2 * np.sin(3 * x)
    exact = vecs @ (np.exp(vals) * (vecs.T @ u0))
    orders = {}
    for flag in (False, True):
        scheme = IMEXRKC(flag)
        errors = []
        for n in levels:
            u = _linear_run(scheme, n, u0, lap, k, lambda dt: _sigma_for(m, dt))
            assert scheme.last_stages == m
            errors.append(np.max(np.abs(u - exact)))
        orders[flag] = _order(errors)
    assert 0.9 <= orders[False] <= 1.5
    assert orders[True] >= 1.9


def test_nonlinear_reaction_is_second_order_with_the_correction():
    """u' = u_xx - u³ + (F_R implicit: w + θ w³ = r solved exactly), self-convergence at m = 6."""
    x, _, lap = _grid(20)
    u0 = 2.0 * np.sin(x) + 0.5 * np.sin(2 * x)

    def solve(r, theta):  # w + θ w³ = r, one real root (Cardano)
        p, q = 1.0 / theta, -r / theta
        disc = np.sqrt(q * q / 4 + p**3 / 27)
        return np.cbrt(-q / 2 + disc) + np.cbrt(-q / 2 - disc)

    def run(flag, n):
        scheme = IMEXRKC(flag)
        u, dt = u0.copy(), 0.5 / n
        for _ in range(n):
            u = scheme.step(u, dt, _sigma_for(6, dt), lap, solve, lambda w: -(w**3))
        return u

    for flag, low, high in ((False, 0.9, 1.5), (True, 1.9, 2.6)):
        ref = run(flag, 1280)
        errors = [np.max(np.abs(run(flag, n) - ref)) for n in (20, 40, 80, 160)]
        assert low <= _order(errors) <= high


@pytest.mark.parametrize("second_order_reaction", [False, True])
@pytest.mark.parametrize("dt", [0.1, 0.01])
def test_stiff_scalar_reaction_stays_bounded(second_order_reaction, dt):
    lam_d, lam_r = 50.0, 1e4
    scheme = IMEXRKC(second_order_reaction)
    w, history = np.array([1.0]), []
    for _ in range(round(1.0 / dt)):
        w = scheme.step(
            w,
            dt,
            lam_d,
            lambda w: -lam_d * w,
            lambda r, t: r / (1 + t * lam_r),
            lambda w: -lam_r * w,
        )
        history.append(abs(w[0]))
    assert np.all(np.diff([1.0, *history]) <= 0.0)  # |w_n| non-increasing
    if dt == 0.01:
        assert history[-1] < 1e-15  # exact solution e^{-10050}


def test_very_stiff_diffusion_many_stages_bounded_and_accurate():
    """Δt σ_J = 1e4: m = 125 stages (eq. 18); noisy data bounded, smooth data accurate."""
    x, dx, lap = _grid(2000)
    sigma = 4 / dx**2
    dt, k, n = 1e4 / sigma, 1.0, 20
    assert stages(dt, sigma) == 125
    lam = 4 / dx**2 * np.sin(dx / 2) ** 2
    rng = np.random.default_rng(0)
    for flag in (False, True):
        scheme = IMEXRKC(flag)
        u, v = np.sin(x), np.sin(x) + 0.5 * rng.uniform(-1, 1, x.size)
        for _ in range(n):
            u = scheme.step(u, dt, sigma, lap, lambda r, t: r / (1 + t * k), lambda w: -k * w)
            v_new = scheme.step(v, dt, sigma, lap, lambda r, t: r / (1 + t * k), lambda w: -k * w)
            assert np.max(np.abs(v_new)) <= np.max(np.abs(v)) + 1e-14
            v = v_new
        assert scheme.last_stages == 125
        exact = math.exp(-(lam + k) * n * dt) * np.sin(x)
        assert np.max(np.abs(u - exact)) / np.max(exact) < 1e-5


def test_state_of_any_shape():
    rng = np.random.default_rng(5)
    w0 = rng.uniform(size=(2, 3, 4))
    scheme = IMEXRKC(True)
    args = (0.1, 30.0, lambda w: -3 * w, lambda r, t: r / (1 + 2 * t), lambda w: -2 * w)
    w = scheme.step(w0, *args)
    flat = scheme.step(w0.ravel(), *args)
    assert w.shape == w0.shape
    np.testing.assert_array_equal(w.ravel(), flat)


@pytest.mark.parametrize("m", [2, 3])
def test_coulomb_friction_stop_is_exact_for_two_and_three_stages(m):
    """Seed scheme + friction: the D-step equals the exact backward-Euler Coulomb update."""
    law = Coulomb(0.3, 9.81)
    dt = 0.01
    qs = np.linspace(-5, 5, 401) * dt * 9.81 * 0.3
    h = np.ones_like(qs)
    scheme = IMEXRKC()

    def solve(r, theta):
        return np.array(law.implicit_update(h, r[0], r[1], r[0], r[1], theta))

    out = scheme.step(
        np.array([qs, 0 * qs]),
        dt,
        _sigma_for(m, dt),
        lambda w: 0 * w,
        solve,
        lambda w: np.array(law.rate(h, w[0], w[1])),
    )
    assert scheme.last_stages == m
    expected = np.sign(qs) * np.maximum(np.abs(qs) - dt * 9.81 * 0.3, 0.0)
    np.testing.assert_allclose(out[0], expected, atol=1e-15)
    assert np.all(out[0][np.abs(qs) < 0.999 * dt * 9.81 * 0.3] == 0.0)


def test_spectral_radius_power():
    x, dx, lap = _grid(100)
    true = np.max(np.abs(np.linalg.eigvalsh(_matrix(100))))
    est = spectral_radius_power(lap, np.sin(x))
    assert true <= est <= 1.25 * true
    assert spectral_radius_power(lambda w: np.ones_like(w), np.ones(5)) == 0.0
