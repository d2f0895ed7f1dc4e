"""The friction laws' per-direction solve, compiled: one pass over the nodes.

:meth:`fem_runout.physics.friction.base.FrictionLaw.implicit_update` solves, for each
direction, ``x + a |x| x = R`` on every wet node (see "Implicit update" in
:mod:`fem_runout.physics.friction.base`). As numpy passes over the few thousand nodes a flow
wets, the setup and the Newton iteration cost more in calls than in arithmetic; this kernel does
the same operations in the same order on each node, so the results are the same bits, and each
node stops at its own convergence (independent of its neighbours and of the partition).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["newton_direction", "solve_direction"]


@numba.njit(cache=True, inline="always")
def _sign(v):
    return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else v)


@numba.njit(cache=True, inline="always")
def _minimum(a, b):
    """``np.minimum``: NaN if either is NaN."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


@numba.njit(cache=True, inline="always")
def newton_direction(h, star, guess, n_i, moving, gc, gt, k, theta, mu, rtol, max_iter):
    """One node of :func:`solve_direction`: ``(x, 1 if Newton did not converge else 0)``."""
    ti = theta * gc * mu * h
    rhs = star - ti * n_i if moving else 0.0
    active = moving and n_i != 0.0
    mag_n = abs(n_i) if active else 1.0
    a = theta * gt * k / (h * h * mag_n) if active else 0.0
    sign, r_abs = _sign(rhs), abs(rhs)
    # upper bounds on the root |x|: |R| (no drag) and sqrt(|R|/a) (drag only)
    bound = _minimum(r_abs, math.sqrt(r_abs / (a if a > 0.0 else 1.0))
                     + (r_abs if a == 0.0 else 0.0))
    g_abs = abs(guess)
    use = _sign(guess) == sign and g_abs <= bound and g_abs + a * (g_abs * g_abs) >= r_abs
    x = g_abs if use else bound
    scale = r_abs + ti * abs(n_i)
    done = False
    for _ in range(max_iter):
        res = x + a * x * x - r_abs
        if not (abs(res) > rtol * scale):
            done = True
            break
        x = x - res / (1.0 + 2.0 * a * x)
    return (sign * x if active else 0.0), (0 if done else 1)


@numba.njit(cache=True)
def _solve(h, star, guess, n_i, moving, gc, gt, k, theta, mu, rtol, max_iter, out):
    failed = 0
    for i in range(h.size):
        out[i], f = newton_direction(h[i], star[i], guess[i], n_i[i], moving[i], gc[i], gt[i],
                                     k[i], theta, mu, rtol, max_iter)
        failed += f
    return failed


def _full(value, n: int) -> np.ndarray:
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))


def solve_direction(h: np.ndarray, star: np.ndarray, guess: np.ndarray, n_i: np.ndarray,
                    moving: np.ndarray, gc, gt, k, theta: float, mu: float, rtol: float,
                    max_iter: int) -> np.ndarray:
    """Newton solve of ``x + a |x| x = R`` for one direction, node by node.

    ``R = q* - θ g_c μ h n`` and ``a = θ g_t k / (h² |n|)`` where the node moves (zero
    elsewhere); Newton on ``|x|`` from the guess if it brackets the root, else from the upper
    bound ``min(|R|, sqrt(|R|/a))``; a node stops once ``|x + a x² - |R|| <= rtol · scale``.

    Args:
        h: Depth (1 where dry), shape (n,).
        star: Right-hand side ``q*`` along the direction.
        guess: Initial guess.
        n_i: The direction's component of the unit vector of ``q*``.
        moving: Nodes above the yield.
        gc: Gravity of the yield term (scalar or per node).
        gt: Gravity of the drag term (scalar or per node).
        k: Drag coefficient (scalar or per node).
        theta: ``θ`` [s].
        mu: Coulomb coefficient.
        rtol: Relative tolerance.
        max_iter: Iterations per node before giving up.

    Returns:
        ``x`` with the sign of ``R``; zero where the node does not move.

    Raises:
        FloatingPointError: If a node did not converge in ``max_iter`` iterations.
    """
    n = h.size
    out = np.empty(n)
    args = [np.ascontiguousarray(a, dtype=np.float64) for a in (h, star, guess, n_i)]
    failed = _solve(*args, np.ascontiguousarray(moving, dtype=np.bool_), _full(gc, n),
                    _full(gt, n), _full(k, n), float(theta), float(mu), float(rtol),
                    int(max_iter), out)
    if failed:
        raise FloatingPointError("friction Newton iteration did not converge")
    return out
