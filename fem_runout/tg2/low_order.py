"""Low-order Rusanov (graph-viscosity) element contributions, well-balanced and positive.

For every owned cell ``K`` and node pair ``i != j`` of ``K``, with ``β_ij`` the antisymmetric part
of ``∫_K φ_i ∇φ_j``, the hydrostatically reconstructed depths
``h*_ij = max(0, h_i + Z_i - max(Z_i, Z_j))`` (Audusse et al. 2004), ``q*_ij = h*_ij u_i`` and the
Rusanov viscosity ``d_ij = λ_ij |β_ij|``,
``λ_ij = max(|u_i·n| + sqrt(g h_i), |u_j·n| + sqrt(g h_j))``:

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
def nodal_velocity(h, qx, qy, tol, kappa, ux, uy):  # noqa: D103 - documented in velocity()
    for i in range(h.shape[0]):
        if h[i] > tol:
            hk = max(h[i], kappa)
            f = 2.0 * h[i] / (h[i] * h[i] + hk * hk)
            ux[i] = qx[i] * f
            uy[i] = qy[i] * f
        else:
            ux[i] = 0.0
            uy[i] = 0.0


def velocity(h, qx, qy, tol: float, kappa: float, ux, uy) -> None:
    """Nodal velocity, desingularised: ``u = 2 h q / (h² + max(h, κ)²)`` (= q/h for h >= κ).

    Zero on dry nodes (``h <= tol``). Written into ``ux``, ``uy``. Kurganov & Petrova (2007):
    a draining layer keeps a bounded velocity instead of ``q / h → ∞``.
    """
    nodal_velocity(h, qx, qy, tol, kappa, ux, uy)


PAIRS = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def pair_coefficients(C: np.ndarray) -> np.ndarray:
    """``β_ab`` = antisymmetric part of ``∫_K φ_a ∇φ_b`` for the 6 node pairs of each cell.

    Args:
        C: (n, 4, 4, 2) cell integrals.

    Returns:
        (n, 6, 2) array in the order of :data:`PAIRS`.
    """
    a, b = PAIRS[:, 0], PAIRS[:, 1]
    return np.ascontiguousarray(0.5 * (C[:, a, b, :] - C[:, b, a, :]))


@numba.njit(cache=True)
def low_order_pass(cells, beta, C, h, qx, qy, z, ux, uy, g, tol, out, cap):
    """Low-order rates per cell and node, and the time-step capacity per node, in one pass.

    Every unordered pair is visited once: its mass and momentum fluxes are antisymmetric
    (``β_ba = -β_ab``, ``d_ab = d_ba``), so node a receives ``+F`` and node b ``-F``.

    Args:
        cells: (n, 4) local node indices of the cells to process.
        beta: (n, 6, 2) pair coefficients (:func:`pair_coefficients`).
        C: (n, 4, 4, 2) ``∫_K φ_i ∇φ_j`` (for the pressure term).
        h: Nodal depth (ghosts up to date).
        qx: Nodal x-momentum.
        qy: Nodal y-momentum.
        z: Nodal elevation.
        ux: Nodal x-velocity (see :func:`velocity`).
        uy: Nodal y-velocity.
        g: Gravity.
        tol: Dry tolerance on h.
        out: (n, 4, 3) low-order rates (overwritten; not multiplied by dt).
        cap: (n_nodes,) ``Σ_j (d_ij + |β_ij·u_i|)`` is added here.
    """
    for k in range(cells.shape[0]):
        nodes = cells[k]
        for a in range(4):
            i = nodes[a]
            eta_i = h[i] + z[i]
            p1 = 0.0
            p2 = 0.0
            for b in range(4):
                if b == a:
                    continue
                j = nodes[b]
                eta_hat = h[j] + z[j]
                if h[j] <= tol:
                    eta_hat = h[j] + min(z[j], eta_i)
                p1 += (eta_hat - eta_i) * C[k, a, b, 0]
                p2 += (eta_hat - eta_i) * C[k, a, b, 1]
            out[k, a, 0] = 0.0
            out[k, a, 1] = -g * h[i] * p1
            out[k, a, 2] = -g * h[i] * p2
        for p in range(6):
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            i = nodes[a]
            j = nodes[b]
            bx = beta[k, p, 0]
            by = beta[k, p, 1]
            zm = max(z[i], z[j])
            hs_ij = max(0.0, h[i] + z[i] - zm)
            hs_ji = max(0.0, h[j] + z[j] - zm)
            nb = np.sqrt(bx * bx + by * by)
            bu_i = bx * ux[i] + by * uy[i]
            bu_j = bx * ux[j] + by * uy[j]
            c_i = np.sqrt(g * max(h[i], 0.0))
            c_j = np.sqrt(g * max(h[j], 0.0))
            d = max(abs(bu_i) + c_i * nb, abs(bu_j) + c_j * nb)
            fm = -(hs_ij * bu_i + hs_ji * bu_j) + d * (hs_ji - hs_ij)
            fx = -bu_i * hs_ij * ux[i] - bu_j * hs_ji * ux[j] + d * (hs_ji * ux[j] - hs_ij * ux[i])
            fy = -bu_i * hs_ij * uy[i] - bu_j * hs_ji * uy[j] + d * (hs_ji * uy[j] - hs_ij * uy[i])
            out[k, a, 0] += fm
            out[k, a, 1] += fx
            out[k, a, 2] += fy
            out[k, b, 0] -= fm
            out[k, b, 1] -= fx
            out[k, b, 2] -= fy
            cap[i] += d + abs(bu_i)
            cap[j] += d + abs(bu_j)


@numba.njit(cache=True)
def reconstructed_surface(cells, h, z, tol, out):
    """Per-cell free surface for the predictor: η on wet nodes, ``min(Z, max wet η)`` on dry.

    Args:
        cells: (n, 4) local node indices.
        h: Nodal depth.
        z: Nodal elevation.
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


@numba.njit(cache=True)
def cell_means(cells, h, qx, qy, eta_cell, out, out_eta):
    """Cell means of the nodal (h, qx, qy) and of the per-cell free surface η̃.

    On a parallelogram the mean of the four nodal values is the exact cell average of the Q1
    interpolant, i.e. the DG0 projection used by the predictor.
    """
    for k in range(cells.shape[0]):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        se = 0.0
        for a in range(4):
            i = cells[k, a]
            s0 += h[i]
            s1 += qx[i]
            s2 += qy[i]
            se += eta_cell[k, a]
        out[k, 0] = 0.25 * s0
        out[k, 1] = 0.25 * s1
        out[k, 2] = 0.25 * s2
        out_eta[k] = 0.25 * se
