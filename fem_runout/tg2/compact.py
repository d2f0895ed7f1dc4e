"""Compiled passes over the active set's compact arrays (row ``k`` is node ``nodes[k]``).

Each pass gives the bits of the array formula in its docstring: NumPy spent more time on
these formulas than on their arithmetic (inner dimensions of 3, strided views, temporaries),
and that time is not shared between ranks (docs/performance.md, session 36).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["antidiffusive", "dry_films", "gather_state", "low_state", "min_ratio", "new_state",
           "scatter_state", "settle", "wet_weighted_max"]


@numba.njit(cache=True)
def gather_state(h, hu, hv, nodes, out):
    """``out[k] = (h, hu, hv)[nodes[k]]`` (one pass)."""
    for k in range(nodes.size):
        i = nodes[k]
        out[k, 0], out[k, 1], out[k, 2] = h[i], hu[i], hv[i]
    return out


@numba.njit(cache=True)
def scatter_state(h, hu, hv, nodes, q):
    """``(h, hu, hv)[nodes[k]] = q[k]`` (one pass)."""
    for k in range(nodes.size):
        i = nodes[k]
        h[i], hu[i], hv[i] = q[k, 0], q[k, 1], q[k, 2]


@numba.njit(cache=True)
def low_state(q0, sums, boundary, m, dt):
    """``q0 + dt (Σ A_L + boundary) / m``: the low-order state (the array formula's bits)."""
    out = np.empty_like(q0)
    for i in range(q0.shape[0]):
        for c in range(3):
            out[i, c] = q0[i, c] + (dt * (sums[i, c] + boundary[i, c])) / m[i]
    return out


@numba.njit(cache=True)
def antidiffusive(high, lo, dt, out):
    """``out = high - dt * lo``: the antidiffusive element contributions, (n, 4, 3)."""
    for k in range(high.shape[0]):
        for a in range(4):
            for c in range(3):
                out[k, a, c] = high[k, a, c] - dt * lo[k, a, c]
    return out


@numba.njit(cache=True)
def new_state(q_low, corr, m):
    """``q_low + corr / m[:, None]``: the limited state."""
    out = np.empty_like(q_low)
    for i in range(q_low.shape[0]):
        for c in range(3):
            out[i, c] = q_low[i, c] + corr[i, c] / m[i]
    return out


@numba.njit(cache=True)
def dry_films(q, tol, m, n_owned):
    """Films thinner than ``tol`` dry out: ``(h, hu, hv) <- (h, hu, hv) min(1, h / tol)``.

    A continuous, monotone map of the depth (``h² / tol`` below ``tol``, the identity above;
    slope at most 2), the velocity kept: a film left behind a flow drains to exactly zero in
    a few steps (``h/tol`` squares each time, down to the underflow) instead of lingering at
    1e-30 m and keeping its cells in the active set. Negative depths are not touched.

    Returns:
        The volume removed at the first ``n_owned`` rows, ``Σ m_i (h_i - h_i²/tol)``.
    """
    dried = 0.0
    for i in range(q.shape[0]):
        h = q[i, 0]
        if h > 0.0 and h < tol:
            r = h / tol
            q[i, 0] = h * r
            q[i, 1] *= r
            q[i, 2] *= r
            if i < n_owned:
                dried += m[i] * (h - q[i, 0])
    return dried


@numba.njit(cache=True)
def settle(q, floor, kappa, kappa2):
    """Round-off depths in ``(floor, 0)`` to 0; thin-layer momenta damped (see ``_finalise``)."""
    for i in range(q.shape[0]):
        if q[i, 0] < 0.0 and q[i, 0] > floor:
            q[i, 0] = 0.0
        if q[i, 0] < kappa:
            ht = max(q[i, 0], 0.0)
            f = 2.0 * ht * ht / (ht * ht + kappa2)
            q[i, 1] *= f
            q[i, 2] *= f


@numba.njit(cache=True)
def min_ratio(m, c, n):
    """``min(m[:n][c > 0] / c[:n][c > 0])``, or ``inf`` if no ``c[:n]`` is positive."""
    best = np.inf
    for i in range(n):
        if c[i] > 0.0:
            best = min(best, m[i] / c[i])
    return best


@numba.njit(cache=True)
def wet_weighted_max(h, s, depth, n):
    """``max(s[:n] * clip(h[:n] / depth, 0, 1))`` (0 if ``n == 0``; NaN if a product is NaN)."""
    if n == 0:
        return 0.0
    best = -np.inf
    for i in range(n):
        w = h[i] / depth
        w = 0.0 if w < 0.0 else (1.0 if w > 1.0 else w)
        v = s[i] * w
        if v != v:
            return v
        best = max(best, v)
    return best
