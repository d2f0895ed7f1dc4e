"""TG2-PC's corrector on an unstructured quadrilateral mesh, cell by cell (seed eqs. 10–12).

The same element contributions as the UFL corrector of :mod:`.forms`, computed per owned cell
from its DG0 half-step state and its neighbours' (:class:`fem_runout.quadmesh.Edges`): the
flux term with ``∫_K ∇φ_a = Σ_{e ∋ a} |e|/2 n_e`` (exact; the UFL form's one-point rule at the
centre gives the same on any quadrilateral, the integrand being bilinear in the reference
coordinates), the edge terms at the edge midpoints:

    A_H[K, a] = dt F(Q_K)·∫_K ∇φ_a
              + Σ_{e ∋ a} dt g_e h̄_e (η_K - η_N)_eff n_K |e| / 4        (interior edges)
              - Σ_{e ∋ a, open} dt g_K h_K (∂Z/∂n) d_e n_K |e| / 4       (open edges)

with the dry-bank surfaces of :mod:`.forms` (``η_eff = η - (1 - w) max(η - η_other, 0)``, wet
weight ``w = min(1, h / (δ + BANK_SLOPE drop))``) and ``d_e`` the distance to the mirrored cell
centre. Why not the UFL facet forms: on the rectangle the vertical and the horizontal facets
give every dof one facet term per form, so the assembled sums are partition-independent; an
unstructured quad mesh has no such split. Here each dof's terms are added in a fixed order —
the cell term, then its two edges sorted by their midpoints — whatever the partition.
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.q1 import jacobians, q1_basis
from fem_runout.tg2.low_order import BANK_SLOPE

__all__ = ["corrector_cells"]


@numba.njit(cache=True)
def _edge_force(hk, ek, hn, en, delta):
    """``h̄ (η_K - η_N)_eff`` of one interior edge (the dry-bank surfaces of :mod:`.forms`)."""
    drop_k, drop_n = max(ek - en, 0.0), max(en - ek, 0.0)
    dry_k = 1.0 - min(1.0, max(hk, 0.0) / (delta + BANK_SLOPE * drop_k))
    dry_n = 1.0 - min(1.0, max(hn, 0.0) / (delta + BANK_SLOPE * drop_n))
    return 0.5 * (hk + hn) * ((ek - dry_k * drop_k) - (en - dry_n * drop_n))


@numba.njit(cache=True)
def corrector_cells(cells, dof0, dofs0, Q, U, eta, G, g_const, delta, dt, neighbour, kind,
                    normal, length, depth, corner_edges, grad_centre, dzdn, out):
    """``out[k, a, :] = A_H`` of the cells ``cells[k]`` (see the module docstring).

    Args:
        cells: (m,) local cells (owned, active).
        dof0: (n_cells,) block index of each local cell in the DG0 vector spaces.
        dofs0: (n_cells,) index of each local cell in the scalar DG0 space.
        Q: DG0 (h, hu, hv) at the half step, blocked by 3.
        U: DG0 velocity, blocked by 2.
        eta: DG0 free surface.
        G: Scalar DG0 ``G`` of the slope form (used when ``g_const`` <= 0).
        g_const: Gravity, or <= 0 for the per-cell ``G``.
        delta: Wet-weight depth δ (the thin depth κ).
        dt: Time step.
        neighbour: Local cell across each edge (-1 on the boundary).
        kind: 0 interior, 1 open, 2 wall, per cell edge.
        normal: Outward unit normals.
        length: Edge lengths.
        depth: Distance to the mirrored cell centre across each edge.
        corner_edges: The two edges at each corner, in summation order.
        grad_centre: ``∫_K ∇φ_a`` per cell and node.
        dzdn: (n_cells, 4) ``∇Z·n`` at the edge midpoints (open edges).
        out: (m, 4, 3) result.
    """
    force = np.empty(4)
    for k in range(cells.shape[0]):
        K = cells[k]
        d = dof0[K]
        hk, qx, qy = Q[3 * d], Q[3 * d + 1], Q[3 * d + 2]
        ux, uy = U[2 * d], U[2 * d + 1]
        ek = eta[dofs0[K]]
        gk = g_const if g_const > 0.0 else G[dofs0[K]]
        for e in range(4):
            w = 0.25 * dt * length[K, e]
            N = neighbour[K, e]
            if N >= 0:
                gn = g_const if g_const > 0.0 else 0.5 * (gk + G[dofs0[N]])
                dn = dof0[N]
                f = gn * _edge_force(hk, ek, Q[3 * dn], eta[dofs0[N]], delta)
                force[e] = w * f
            elif kind[K, e] == 1:
                force[e] = -w * gk * hk * dzdn[K, e] * depth[K, e]
            else:
                force[e] = 0.0
        for a in range(4):
            gx, gy = grad_centre[K, a, 0], grad_centre[K, a, 1]
            m0 = dt * (qx * gx + qy * gy)
            m1 = dt * (qx * ux * gx + qx * uy * gy)
            m2 = dt * (qy * ux * gx + qy * uy * gy)
            for j in range(2):
                e = corner_edges[K, a, j]
                m1 += force[e] * normal[K, e, 0]
                m2 += force[e] * normal[K, e, 1]
            out[k, a, 0] = m0
            out[k, a, 1] = m1
            out[k, a, 2] = m2


def edge_dzdn(z: np.ndarray, coords: np.ndarray, cell_nodes: np.ndarray,
              normal: np.ndarray) -> np.ndarray:
    """``∇Z·n`` of the Q1 bed at every edge midpoint of every local cell, from inside the cell.

    Args:
        z: Nodal bed elevation.
        coords: (n_nodes, 2) node coordinates.
        cell_nodes: (n_cells, 4) local nodes of the cells.
        normal: (n_cells, 4, 2) outward unit normals of the edges.

    Returns:
        (n_cells, 4).
    """
    mids = np.array([[0.5, 0.0], [0.0, 0.5], [1.0, 0.5], [0.5, 1.0]])  # edges 0..3
    _, dphi = q1_basis(mids)  # (edge, node, ref dir)
    xc, zc = coords[cell_nodes], z[cell_nodes]
    J = jacobians(xc, dphi)  # dx_a / dX_b per cell and edge
    dz = np.einsum("ck,ekb->ceb", zc, dphi)  # dZ / dX_b
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    gx = (J[..., 1, 1] * dz[..., 0] - J[..., 1, 0] * dz[..., 1]) / det
    gy = (-J[..., 0, 1] * dz[..., 0] + J[..., 0, 0] * dz[..., 1]) / det
    return gx * normal[..., 0] + gy * normal[..., 1]
