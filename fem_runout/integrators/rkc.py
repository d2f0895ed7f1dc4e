"""IMEX Runge-Kutta-Chebyshev scheme of seed eqs. 17-19 (explicit diffusion, implicit reaction).

The second-order IMEX-RKC of seed eq. 17, with the coefficients of seed eq. 19 and the stage
count of seed eq. 18.

For ``w' = F_D(w) + F_R(w)`` and a step ``Δt`` with ``m`` stages (``θ = μ̃_1 Δt``)::

    W_0 = w_n
    W_1 - θ F_R(W_1) = W_0 + μ̃_1 Δt F_D(W_0)
    W_j - θ F_R(W_j) = (1-μ_j-ν_j) W_0 + μ_j W_{j-1} + ν_j W_{j-2}
                       + μ̃_j Δt F_D(W_{j-1}) + γ̃_j Δt F_D(W_0)
                       + (γ̃_j - (1-μ_j-ν_j) μ̃_1) Δt F_R(W_0) - ν_j μ̃_1 Δt F_R(W_{j-2})
                       [+ κ Δt (F_R(W_{m-1}) - F_R(W_0))   for j = m, see below]
    w_{n+1} = W_m

Coefficients (Chebyshev ``T_j`` of seed eq. 19, damping ``ε = 2/13``)::

    ω0 = 1 + ε/m²,   ω1 = T'_m(ω0)/T''_m(ω0),   b_j = T''_j(ω0)/T'_j(ω0)² (j >= 2),
    b_0 = b_2,   b_1 = 1/ω0,
    μ_j = 2 b_j ω0/b_{j-1},  ν_j = -b_j/b_{j-2},  μ̃_j = 2 b_j ω1/b_{j-1},  μ̃_1 = b_1 ω1,
    γ̃_j = -(1 - b_{j-1} T_{j-1}(ω0)) μ̃_j,   c_j = μ_j c_{j-1} + ν_j c_{j-2} + μ̃_j + γ̃_j.

Where this differs from the seed's print, and why (all checked in ``tests/test_rkc.py``):

* **b_1.** The seed prints ``b_0 = b_1 = b_2`` (the explicit RKC of Sommeijer, Shampine &
  Verwer 1997, where ``b_1`` is free). In the IMEX scheme ``b_1`` is not free: consistency of
  the implicit part needs ``μ_j μ̃_1 = μ̃_j``, i.e. ``b_1 = 1/ω0``, the choice of the IMEX-RKC of
  Verwer, Sommeijer & Hundsdorfer (2004) and of the IRKC code (Shampine, Sommeijer & Verwer
  2006). With ``b_1 = b_2`` the printed scheme has an O(1) error for any reaction. With
  ``b_1 = 1/ω0`` the seed's ``F_R^0`` coefficient ``γ̃_j μ̃_1 μ_j/μ̃_j - (1-μ_j-ν_j) μ̃_1`` is
  exactly ``γ̃_j - (1-μ_j-ν_j) μ̃_1`` as above; ``c_1 = μ̃_1 = c_2`` (the seed's
  ``c_1 = c_2/(4ω0)`` belongs to ``b_1 = b_2``) and the ``c_j`` are non-decreasing, ``c_m = 1``.
* **Order in the reaction.** Writing ``V_j = W_j - θ F_R(W_j)`` shows that, for linear
  ``F_D = λ_D``, ``F_R = λ_R``, the scheme is explicit RKC in ``ζ = Δt (λ_D + λ_R)/(1 - θ λ_R)``:
  ``w_{n+1} = P_m(ζ) w_n``, ``P_m(ζ) = a_m + b_m T_m(ω0 + ω1 ζ)``. Since ``1/θ < β(m)/Δt``,
  ``ζ ∈ [-β(m), 0]`` whenever ``Δt λ_D ∈ [-β(m), 0]`` and ``λ_R <= 0``: unconditionally stable
  in the reaction. But ``ζ = z + θ λ_R z + ...``: the seed's scheme is second order for
  ``F_R = 0`` and only **first order** in the reaction (local error ``μ̃_1 Δt² F_R' F``, the
  term IRKC's error estimator measures). ``IMEXRKC(second_order_reaction=True)`` adds the
  zero-sum term ``κ Δt (F_R(W_{m-1}) - F_R(W_0))``, ``κ = -μ̃_1/c_{m-1}``, to the last stage:
  stage times and diffusion part unchanged, the ``θ`` error cancelled, second order for
  diffusion, reaction and coupling; still ``|w_{n+1}| <= |w_n|`` on the same region (checked
  on a grid). Its price: for stiff reactions ``w_{n+1}/w_n`` tends to a value in
  ``[-0.64, 0.61]`` (a sign change), and it handles Coulomb friction worse (below). The
  default is the seed's scheme.
* **Stiff damping.** The seed's scheme is not L-stable: as ``Δt λ_R → -∞``,
  ``w_{n+1}/w_n → P_m(-ω0/ω1) ∈ [0.33, 0.96]`` (m = 2..300; e.g. 0.95 for m = 4), so a very
  stiff linear reaction mode decays by that factor per step instead of vanishing.

``F_R(W_j)`` is evaluated with ``f_reaction`` (for friction: the explicit rate with the relaxed
sign of seed eq. 20), for ``j <= m-2`` (and ``m-1`` with the correction).

**Nonsmooth reactions (Coulomb friction).** For the reaction alone, a backward-Euler solve
``q - Δt r(q) = q*`` is exact for Coulomb friction (constant deceleration, exact stop). The
seed's scheme reproduces it exactly for ``m = 2`` (``μ̃_1 = 1``: the first stage is that
solve) and ``m = 3``. For ``m >= 4``, ``θ = μ̃_1 Δt ≈ 3Δt/m²`` is small and the stop is carried by
the explicit ``F_R`` terms: a flow that should stop within the step keeps or reverses up to
about 15 % of the friction impulse ``Δt g μ h`` (75 % with the second-order correction, which
already deviates by 25 % at ``m = 2``). Where exact stopping matters and ``m >= 4``, apply the
friction as its own backward-Euler solve after an RKC step of the diffusion alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = [
    "DAMPING",
    "IMEXRKC",
    "RKCCoefficients",
    "rkc_coefficients",
    "spectral_radius_power",
    "stability_polynomial",
    "stages",
]

Array = np.ndarray
#: Damping parameter ``ε`` of seed eq. 19.
DAMPING = 2.0 / 13.0


@dataclass(frozen=True)
class RKCCoefficients:
    """Coefficients of seed eq. 19 for ``m`` stages (arrays indexed by the stage ``j = 0..m``).

    Attributes:
        m: Number of stages (>= 2).
        omega0, omega1: ``ω0 = 1 + ε/m²`` and ``ω1 = T'_m(ω0)/T''_m(ω0)``.
        b, mu, nu, mu_t, gamma_t, c: ``b_j, μ_j, ν_j, μ̃_j, γ̃_j, c_j`` (unused entries 0).
        cheb: ``T_j(ω0)``.
        kappa: Second-order reaction correction ``κ = -μ̃_1/c_{m-1}`` (module docstring).
        beta: Real stability boundary ``β(m) = (1 + ω0)/ω1 ≈ 0.653 (m² - 1)``.
    """

    m: int
    omega0: float
    omega1: float
    b: Array
    mu: Array
    nu: Array
    mu_t: Array
    gamma_t: Array
    c: Array
    cheb: Array
    kappa: float
    beta: float


def _chebyshev(m: int, x: float) -> tuple[Array, Array, Array]:
    """``T_j(x), T'_j(x), T''_j(x)`` for ``j = 0..m`` by the recurrence of seed eq. 19."""
    t, dt, d2t = np.zeros(m + 1), np.zeros(m + 1), np.zeros(m + 1)
    t[0], t[1], dt[1] = 1.0, x, 1.0
    for j in range(2, m + 1):
        t[j] = 2.0 * x * t[j - 1] - t[j - 2]
        dt[j] = 2.0 * t[j - 1] + 2.0 * x * dt[j - 1] - dt[j - 2]
        d2t[j] = 4.0 * dt[j - 1] + 2.0 * x * d2t[j - 1] - d2t[j - 2]
    return t, dt, d2t


@lru_cache(maxsize=256)
def rkc_coefficients(m: int) -> RKCCoefficients:
    """Coefficients of seed eq. 19 for ``m >= 2`` stages (cached; arrays are read-only)."""
    if m < 2:
        raise ValueError(f"IMEX-RKC needs m >= 2 stages, got {m}")
    w0 = 1.0 + DAMPING / m**2
    t, dt, d2t = _chebyshev(m, w0)
    w1 = dt[m] / d2t[m]
    b = np.zeros(m + 1)
    b[2:] = d2t[2:] / dt[2:] ** 2
    b[0], b[1] = b[2], 1.0 / w0
    mu, nu, mu_t, gamma_t, c = (np.zeros(m + 1) for _ in range(5))
    mu_t[1] = c[1] = b[1] * w1
    for j in range(2, m + 1):
        mu[j] = 2.0 * b[j] * w0 / b[j - 1]
        nu[j] = -b[j] / b[j - 2]
        mu_t[j] = 2.0 * b[j] * w1 / b[j - 1]
        gamma_t[j] = -(1.0 - b[j - 1] * t[j - 1]) * mu_t[j]
        c[j] = mu[j] * c[j - 1] + nu[j] * c[j - 2] + mu_t[j] + gamma_t[j]
    for arr in (b, mu, nu, mu_t, gamma_t, c, t):
        arr.flags.writeable = False
    kappa = -mu_t[1] / c[m - 1]
    return RKCCoefficients(m, w0, w1, b, mu, nu, mu_t, gamma_t, c, t, kappa, (1.0 + w0) / w1)


def stages(dt: float, sigma: float) -> int:
    """Return the stage count of seed eq. 18: ``m = 1 + ceil(sqrt(1 + Δt σ_J / 0.653))`` (>= 2).

    ``σ_J`` is the spectral radius of the Jacobian of ``F_D``. This gives
    ``Δt σ_J <= 0.653 ((m-1)² - 1) < β(m)``, a safe margin on the stability boundary.
    """
    if dt < 0 or sigma < 0 or not math.isfinite(dt * sigma):
        raise ValueError(f"stages needs finite dt >= 0 and sigma >= 0, got {dt!r}, {sigma!r}")
    return max(2, 1 + math.ceil(math.sqrt(1.0 + dt * sigma / 0.653)))


def stability_polynomial(m: int, z: Array) -> Array:
    """RKC stability polynomial ``P_m(z) = a_m + b_m T_m(ω0 + ω1 z)``, ``a_m = 1 - b_m T_m(ω0)``.

    ``|P_m| <= 1`` on ``[-β(m), 0]``; the IMEX scheme gives ``P_m(ζ)`` (module docstring).
    """
    co = rkc_coefficients(m)
    x = co.omega0 + co.omega1 * np.asarray(z, dtype=float)
    tm_prev, tm = np.ones_like(x), x
    for _ in range(2, m + 1):
        tm_prev, tm = tm, 2.0 * x * tm - tm_prev
    return 1.0 - co.b[m] * co.cheb[m] + co.b[m] * tm


class IMEXRKC:
    """The IMEX-RKC step of seed eq. 17 (see the module docstring for the coefficients).

    Args:
        second_order_reaction: Add the last-stage term ``κ Δt (F_R(W_{m-1}) - F_R(W_0))`` that
            makes the reaction second order (for smooth reactions). ``False`` (default) is the
            seed's scheme: second order for the diffusion, first order in the reaction,
            stiff decay factor ``P_m(-ω0/ω1) >= 0.5``, exact Coulomb stop for ``m <= 3``.

    Attributes:
        last_stages: Number of stages ``m`` used by the last :meth:`step` (0 before).
    """

    def __init__(self, second_order_reaction: bool = False) -> None:
        self.second_order_reaction = second_order_reaction
        self.last_stages = 0

    def step(
        self,
        w0: Array,
        dt: float,
        sigma: float,
        f_diffusion: Callable[[Array], Array],
        solve_reaction: Callable[[Array, float], Array],
        f_reaction: Callable[[Array], Array],
    ) -> Array:
        """Advance ``w' = F_D(w) + F_R(w)`` by ``dt`` with ``m = stages(dt, sigma)`` stages.

        Args:
            w0: State at ``t_n`` (numpy array of any shape; not modified).
            dt: Time step [s].
            sigma: Spectral radius ``σ_J`` of the Jacobian of ``F_D`` [1/s].
            f_diffusion: ``w -> F_D(w)``, explicit rate, same shape as ``w``.
            solve_reaction: ``(rhs, θ) -> w`` solving ``w - θ F_R(w) = rhs``.
            f_reaction: ``w -> F_R(w)``, explicit reaction rate.

        Returns:
            ``W_m``, the state at ``t_n + dt``.
        """
        m = stages(dt, sigma)
        co = rkc_coefficients(m)
        self.last_stages = m
        w0 = np.asarray(w0, dtype=float)
        theta = co.mu_t[1] * dt
        fd0 = f_diffusion(w0)
        fr0 = f_reaction(w0)
        rhs = w0 + theta * fd0
        w_prev2, w_prev = w0, solve_reaction(rhs, theta)
        fr_prev2, fr_prev = fr0, f_reaction(w_prev)
        for j in range(2, m + 1):
            rhs = self._stage_rhs(co, j, dt, w0, w_prev, w_prev2, fd0, fr0, fr_prev2)
            rhs += co.mu_t[j] * dt * f_diffusion(w_prev)
            if j == m and self.second_order_reaction:
                rhs += co.kappa * dt * (fr_prev - fr0)
            w_new = solve_reaction(rhs, theta)
            if j < m:
                need = j <= m - 2 or self.second_order_reaction
                fr_new = f_reaction(w_new) if need else fr_prev
                w_prev2, w_prev, fr_prev2, fr_prev = w_prev, w_new, fr_prev, fr_new
        return w_new

    @staticmethod
    def _stage_rhs(
        co: RKCCoefficients,
        j: int,
        dt: float,
        w0: Array,
        w_prev: Array,
        w_prev2: Array,
        fd0: Array,
        fr0: Array,
        fr_prev2: Array,
    ) -> Array:
        """Right-hand side of stage ``j >= 2`` of seed eq. 17, without ``μ̃_j Δt F_D(W_{j-1})``."""
        mu, nu, g = co.mu[j], co.nu[j], co.gamma_t[j]
        theta = co.mu_t[1] * dt
        return (
            (1.0 - mu - nu) * w0
            + mu * w_prev
            + nu * w_prev2
            + g * dt * fd0
            + (g * dt - (1.0 - mu - nu) * theta) * fr0
            - nu * theta * fr_prev2
        )


def spectral_radius_power(
    f: Callable[[Array], Array],
    w: Array,
    iters: int = 50,
    rtol: float = 0.01,
    safety: float = 1.2,
) -> float:
    """Estimate the spectral radius of the Jacobian of ``f`` at ``w`` by a nonlinear power method.

    Finite differences ``f(w + δ v) - f(w)`` (``δ`` relative ``sqrt(eps)``) replace the Jacobian,
    as in the RKC codes; the estimate is multiplied by ``safety``. The run-out solver instead
    bounds ``σ_J`` by Gershgorin on the assembled diffusion operator (seed §3.1.1); this helper
    is for generic use and tests.

    Args:
        f: Rate function (any array shape).
        w: State at which the Jacobian is taken.
        iters: Maximum number of power iterations.
        rtol: Stop when two successive estimates differ by less than ``rtol`` (relative).
        safety: Factor applied to the estimate (an upper bound is wanted).

    Returns:
        ``safety × |J v| / |v|`` at the last iterate (0 for a constant ``f``).
    """
    w = np.asarray(w, dtype=float)
    f0 = np.asarray(f(w), dtype=float)
    size = max(_norm(w), 1.0)
    delta = math.sqrt(np.finfo(float).eps) * size
    rng = np.random.default_rng(12345)
    v = rng.standard_normal(w.shape)
    v *= delta / _norm(v)
    sigma = 0.0
    for _ in range(iters):
        df = np.asarray(f(w + v), dtype=float) - f0
        norm_df = _norm(df)
        new = norm_df / delta
        if norm_df == 0.0:
            return 0.0
        v = df * (delta / norm_df)
        if abs(new - sigma) <= rtol * new:
            return safety * new
        sigma = new
    return safety * sigma


def _norm(x: np.ndarray) -> float:
    """Euclidean norm from a correctly rounded sum (``math.fsum``): the same bits on any CPU.

    ``np.linalg.norm`` calls BLAS, whose kernels (and last bits) follow the CPU.
    """
    a = np.ravel(np.asarray(x, dtype=float))
    return math.sqrt(math.fsum(a * a))
