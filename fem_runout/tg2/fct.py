"""Zalesak flux-corrected transport on cell–node arrays (seed eqs. 13–15).

The high-order (TG2-PC) and low-order (Rusanov) updates are both sums of element contributions
``A[K, i]`` to the nodes ``i`` of each cell ``K``. Their difference, the antidiffusive element
contribution, is added back with one factor ``α_K ∈ [0, 1]`` per cell (a Q0 field, eq. 15):

    m_i u_i^{n+1} = m_i u_i^L + Σ_K α_K A[K, i]

Zalesak's choice of ``α_K`` keeps every ``u_i^{n+1}`` inside
``[u_i^L + Q⁻_i/m_i, u_i^L + Q⁺_i/m_i]``:
``P^±_i`` are the sums of positive/negative contributions to node i, ``R^±_i = min(1, Q^±_i/P^±_i)``
and ``α_K = min_i (R⁺_i if A[K,i] > 0 else R⁻_i)``. Because each cell's contributions to a
conserved variable sum to zero, the limited update stays conservative.

The functions here are local to one rank; the solver sums ``P^±`` and reduces the bounds across
ranks between the calls.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def antidiffusive_sums(cells, aec, pplus, pminus):
    """Add the positive and negative parts of ``aec[K, i]`` into ``pplus``/``pminus`` per node."""
    for k in range(cells.shape[0]):
        for a in range(4):
            v = aec[k, a]
            if v > 0.0:
                pplus[cells[k, a]] += v
            else:
                pminus[cells[k, a]] += v


@numba.njit(cache=True)
def patch_extrema(cells, values, mask, vmax, vmin):
    """Extend ``vmax``/``vmin`` per node by the extrema of ``values`` over each cell's nodes.

    Only nodes with ``mask`` true contribute; every node of a cell receives the cell's extrema,
    so after all cells (and a cross-rank reduction) ``vmax[i]`` is the maximum over the patch of
    cells around ``i``.
    """
    for k in range(cells.shape[0]):
        hi = -np.inf
        lo = np.inf
        for a in range(4):
            i = cells[k, a]
            if mask[i]:
                hi = max(hi, values[i])
                lo = min(lo, values[i])
        for a in range(4):
            i = cells[k, a]
            vmax[i] = max(vmax[i], hi)
            vmin[i] = min(vmin[i], lo)


def zalesak_ratios(
    pplus: np.ndarray, pminus: np.ndarray, qplus: np.ndarray, qminus: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Nodal ratios ``R^± = min(1, Q^± / P^±)`` (1 where nothing is added).

    Args:
        pplus: Sum of positive contributions (>= 0).
        pminus: Sum of negative contributions (<= 0).
        qplus: Room above the low-order value, ``m_i (u_max - u^L)`` (>= 0).
        qminus: Room below, ``m_i (u_min - u^L)`` (<= 0).
    """
    rplus = np.ones_like(pplus)
    rminus = np.ones_like(pminus)
    pos = pplus > 0.0
    neg = pminus < 0.0
    with np.errstate(over="ignore"):  # Q/P overflows for subnormal P; min(1, inf) = 1 is right
        rplus[pos] = np.minimum(1.0, np.maximum(qplus[pos], 0.0) / pplus[pos])
        rminus[neg] = np.minimum(1.0, np.minimum(qminus[neg], 0.0) / pminus[neg])
    return rplus, rminus


@numba.njit(cache=True)
def cell_factors(cells, aec, rplus, rminus, alpha):
    """``α_K = min(α_K, min_i R^±_i)`` with the sign of ``aec[K, i]`` choosing R⁺ or R⁻."""
    for k in range(cells.shape[0]):
        a_k = alpha[k]
        for a in range(4):
            i = cells[k, a]
            v = aec[k, a]
            if v > 0.0:
                a_k = min(a_k, rplus[i])
            elif v < 0.0:
                a_k = min(a_k, rminus[i])
        alpha[k] = a_k


@numba.njit(cache=True)
def scatter_cells(cells, contrib, weight, out):
    """``out[i, c] += weight[K] * contrib[K, a, c]`` for node ``i = cells[K, a]``."""
    for k in range(cells.shape[0]):
        w = weight[k]
        for a in range(4):
            i = cells[k, a]
            for c in range(contrib.shape[2]):
                out[i, c] += w * contrib[k, a, c]


def limit_serial(
    cells: np.ndarray,
    aec: np.ndarray,
    u_low: np.ndarray,
    mass: np.ndarray,
    u_max: np.ndarray,
    u_min: np.ndarray,
) -> np.ndarray:
    """Zalesak factors for one scalar on one rank (the building blocks chained together).

    Args:
        cells: (n, 4) node indices.
        aec: (n, 4) antidiffusive element contributions.
        u_low: Low-order nodal solution.
        mass: Lumped nodal mass.
        u_max: Upper bound per node (>= u_low).
        u_min: Lower bound per node (<= u_low).

    Returns:
        ``α`` per cell.
    """
    pplus = np.zeros_like(u_low)
    pminus = np.zeros_like(u_low)
    antidiffusive_sums(cells, aec, pplus, pminus)
    rplus, rminus = zalesak_ratios(pplus, pminus, mass * (u_max - u_low), mass * (u_min - u_low))
    alpha = np.ones(cells.shape[0])
    cell_factors(cells, aec, rplus, rminus, alpha)
    return alpha
