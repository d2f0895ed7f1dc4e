"""Low-order Rusanov (graph-viscosity) element contributions, well-balanced and positive.

For every owned cell ``K`` and node pair ``i != j`` of ``K``, with ``β_ij`` the antisymmetric part
of ``∫_K φ_i ∇φ_j``, the hydrostatically reconstructed depths
``h*_ij = max(0, h_i + Z_i - max(Z_i, Z_j))`` (Audusse et al. 2004), ``q*_ij = h*_ij u_i`` and the
Rusanov viscosity ``d_ij = λ_ij |β_ij|``, ``λ_ij = max(|u_i·n| + sqrt(g h_i), |u_j·n| + sqrt(g h_j))``:

    mass_i += -β_ij·(q*_ij + q*_ji) + d_ij (h*_ji - h*_ij)
    mom_i  += -(β_ij·u_i) q*_ij - (β_ij·u_j) q*_ji + d_ij (q*_ji - q*_ij)
    mom_i  += -g h_i Σ_j (η̂_ij - η_i) ∫_K φ_i ∇φ_j   (j over all nodes of K; Σ_j ∫φ_i∇φ_j = 0)

where ``η̂_ij = η_j`` if node j is wet and ``h_j + min(Z_j, η_i)`` if it is dry: a dry bank above
the water pushes nothing. Each cell's mass contributions sum to zero (conservation), vanish for
a lake at rest (also with emerged dry ground), and the update is positive for
``dt <= m_i / Σ_j (d_ij + |β_ij·u_i|)`` (this bound, with the eigenvalues ``|u·n| ± sqrt(g h)`` of
the full system, sets the time step). This is the low-order scheme of seed eq. 15 that the FCT
limiter blends with TG2-PC.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def nodal_velocity(h, qx, qy, tol, ux, uy):  # noqa: D103 - documented in velocity()
    for i in range(h.shape[0]):
        if h[i] > tol:
            ux[i] = qx[i] / h[i]
            uy[i] = qy[i] / h[i]
        else:
            ux[i] = 0.0
            uy[i] = 0.0


def velocity(h: np.ndarray, qx: np.ndarray, qy: np.ndarray, tol: float, ux, uy) -> None:
    """Nodal velocity ``q / h`` where ``h > tol``, zero on dry nodes (written into ux, uy)."""
    nodal_velocity(h, qx, qy, tol, ux, uy)


@numba.njit(cache=True)
def _pair(i, j, bx, by, h, z, ux, uy, g):
    """Reconstructed depths and Rusanov viscosity of one node pair."""
    zm = max(z[i], z[j])
    hs_ij = max(0.0, h[i] + z[i] - zm)
    hs_ji = max(0.0, h[j] + z[j] - zm)
    nb = np.sqrt(bx * bx + by * by)
    lam = 0.0
    if nb > 0.0:
        un_i = abs(ux[i] * bx + uy[i] * by) / nb
        un_j = abs(ux[j] * bx + uy[j] * by) / nb
        lam = max(un_i + np.sqrt(g * max(h[i], 0.0)), un_j + np.sqrt(g * max(h[j], 0.0)))
    return hs_ij, hs_ji, lam * nb


@numba.njit(cache=True)
def low_order_contributions(cells, C, h, qx, qy, z, ux, uy, g, tol, out):
    """Fill ``out[K, i, :]`` with the low-order rates (mass, x-, y-momentum) of cell K.

    Args:
        cells: (n, 4) local node indices of the cells to process.
        C: (n, 4, 4, 2) ``∫_K φ_i ∇φ_j``.
        h, qx, qy, z: Nodal depth, momenta and elevation (local, ghosts up to date).
        ux, uy: Nodal velocity (see :func:`velocity`).
        g: Gravity.
        tol: Dry tolerance on h.
        out: (n, 4, 3) output rates (not yet multiplied by dt).
    """
    for k in range(cells.shape[0]):
        nodes = cells[k]
        for a in range(4):
            i = nodes[a]
            eta_i = h[i] + z[i]
            m0 = 0.0
            m1 = 0.0
            m2 = 0.0
            p1 = 0.0
            p2 = 0.0
            for b in range(4):
                j = nodes[b]
                eta_hat = h[j] + z[j]
                if h[j] <= tol:
                    eta_hat = h[j] + min(z[j], eta_i)
                p1 += (eta_hat - eta_i) * C[k, a, b, 0]
                p2 += (eta_hat - eta_i) * C[k, a, b, 1]
                if b == a:
                    continue
                bx = 0.5 * (C[k, a, b, 0] - C[k, b, a, 0])
                by = 0.5 * (C[k, a, b, 1] - C[k, b, a, 1])
                hs_ij, hs_ji, d = _pair(i, j, bx, by, h, z, ux, uy, g)
                bu_i = bx * ux[i] + by * uy[i]
                bu_j = bx * ux[j] + by * uy[j]
                m0 += -(hs_ij * bu_i + hs_ji * bu_j) + d * (hs_ji - hs_ij)
                m1 += -bu_i * hs_ij * ux[i] - bu_j * hs_ji * ux[j] + d * (
                    hs_ji * ux[j] - hs_ij * ux[i])
                m2 += -bu_i * hs_ij * uy[i] - bu_j * hs_ji * uy[j] + d * (
                    hs_ji * uy[j] - hs_ij * uy[i])
            out[k, a, 0] = m0
            out[k, a, 1] = m1 - g * h[i] * p1
            out[k, a, 2] = m2 - g * h[i] * p2


@numba.njit(cache=True)
def outflow_capacity(cells, C, h, z, ux, uy, g, out):
    """Accumulate ``Σ_j (d_ij + |β_ij·u_i|)`` per node into ``out`` (for the time step)."""
    for k in range(cells.shape[0]):
        nodes = cells[k]
        for a in range(4):
            i = nodes[a]
            s = 0.0
            for b in range(4):
                if b == a:
                    continue
                j = nodes[b]
                bx = 0.5 * (C[k, a, b, 0] - C[k, b, a, 0])
                by = 0.5 * (C[k, a, b, 1] - C[k, b, a, 1])
                _, _, d = _pair(i, j, bx, by, h, z, ux, uy, g)
                s += d + abs(bx * ux[i] + by * uy[i])
            out[i] += s


@numba.njit(cache=True)
def reconstructed_surface(cells, h, z, tol, out):
    """Per-cell free surface for the predictor: η on wet nodes, ``min(Z, max wet η)`` on dry.

    Args:
        cells: (n, 4) local node indices.
        h, z: Nodal depth and elevation.
        tol: Dry tolerance.
        out: (n, 4) output, the DQ1 coefficients of η̃ (lake at rest gives a constant η̃).
    """
    for k in range(cells.shape[0]):
        nodes = cells[k]
        top = -np.inf
        for a in range(4):
            i = nodes[a]
            if h[i] > tol:
                top = max(top, h[i] + z[i])
        for a in range(4):
            i = nodes[a]
            if h[i] > tol:
                out[k, a] = h[i] + z[i]
            else:
                out[k, a] = h[i] + min(z[i], top) if top > -np.inf else h[i] + z[i]
