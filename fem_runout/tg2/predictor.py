"""TG2-PC's DG0 predictor, cell by cell (seed eq. 10, first line).

The integral of the UFL form :func:`.forms.predictor_form`, computed per cell by the same
2 × 2 Gauss rule FFCx uses for its quadrature degree 3 on quadrilaterals, with the bilinear
map of each cell (exact on a parallelogram: every integrand is then a polynomial of degree
≤ 3 in each reference coordinate):

    b_K = -dt/2 ∫_K (∇·q,  ∇·(q u_x) + g h ∂_x η̃,  ∇·(q u_y) + g h ∂_y η̃)

with ``q = (hu, hv)``, ``u`` the Q1 nodal velocity, ``∇·(q ⊗ u)_i = ∂_j (q_i u_j)`` by the
product rule, ``η̃`` the per-cell free surface (discontinuous Q1) and ``g`` the constant, or
the slope form's per-cell ``G``. Each cell's result depends on its own data only, so a ghost
cell gives the owner's bits and no exchange is needed.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["predictor_cells"]

_A = 0.5 - 0.5 / np.sqrt(3.0)
#: the 2 × 2 Gauss points on the unit square and their common weight
_POINTS = np.array([[_A, _A], [1.0 - _A, _A], [_A, 1.0 - _A], [1.0 - _A, 1.0 - _A]])
_WEIGHT = 0.25


@numba.njit(cache=True)
def _gradients(xc, s, t, grad):
    """Physical gradients of the four Q1 basis functions at ``(s, t)``; returns ``|det J|``."""
    # reference gradients of (1-s)(1-t), s(1-t), (1-s)t, st
    rs = (-(1.0 - t), 1.0 - t, -t, t)
    rt = (-(1.0 - s), -s, 1.0 - s, s)
    j00 = j01 = j10 = j11 = 0.0
    for a in range(4):
        j00 += xc[a, 0] * rs[a]
        j01 += xc[a, 0] * rt[a]
        j10 += xc[a, 1] * rs[a]
        j11 += xc[a, 1] * rt[a]
    det = j00 * j11 - j01 * j10
    for a in range(4):
        grad[a, 0] = (j11 * rs[a] - j10 * rt[a]) / det
        grad[a, 1] = (-j01 * rs[a] + j00 * rt[a]) / det
    return abs(det)


@numba.njit(cache=True)
def predictor_cells(cells, cell_nodes, coords, h, hu, hv, ux, uy, eta, dofsd, G, dofs0,
                    g_const, dt, dof0, b):
    """``b[3 dof0[K] + c] = b_K[c]`` for the cells ``cells`` (see the module docstring).

    Args:
        cells: (m,) local cells.
        cell_nodes: (n_cells, 4) local Q1 nodes in basix's reference order.
        coords: (n_nodes, 2) node coordinates.
        h: Nodal depth.
        hu: Nodal x momentum.
        hv: Nodal y momentum.
        ux: Nodal x velocity.
        uy: Nodal y velocity.
        eta: Discontinuous Q1 free surface η̃, dofs ``dofsd``.
        dofsd: (n_cells, 4) dofs of η̃ per cell, in the nodes' order.
        G: Scalar DG0 ``G`` of the slope form (used when ``g_const`` <= 0), dofs ``dofs0``.
        dofs0: (n_cells,) index of each cell in the scalar DG0 space.
        g_const: Gravity, or <= 0 for the per-cell ``G``.
        dt: Time step.
        dof0: (n_cells,) block index of each cell in the DG0 vector space.
        b: DG0 (h, hu, hv) vector, blocked by 3.
    """
    xc = np.empty((4, 2))
    grad = np.empty((4, 2))
    for k in range(cells.shape[0]):
        K = cells[k]
        for a in range(4):
            xc[a, 0] = coords[cell_nodes[K, a], 0]
            xc[a, 1] = coords[cell_nodes[K, a], 1]
        g = g_const if g_const > 0.0 else G[dofs0[K]]
        r0 = r1 = r2 = 0.0
        for p in range(4):
            s, t = _POINTS[p, 0], _POINTS[p, 1]
            w = _WEIGHT * _gradients(xc, s, t, grad)
            phi = ((1.0 - s) * (1.0 - t), s * (1.0 - t), (1.0 - s) * t, s * t)
            hq = qx = qy = vx = vy = 0.0
            qxx = qxy = qyx = qyy = vxx = vxy = vyx = vyy = ex = ey = 0.0
            for a in range(4):
                i = cell_nodes[K, a]
                f, gx, gy = phi[a], grad[a, 0], grad[a, 1]
                hq += f * h[i]
                qx += f * hu[i]
                qy += f * hv[i]
                vx += f * ux[i]
                vy += f * uy[i]
                qxx += gx * hu[i]
                qxy += gy * hu[i]
                qyx += gx * hv[i]
                qyy += gy * hv[i]
                vxx += gx * ux[i]
                vxy += gy * ux[i]
                vyx += gx * uy[i]
                vyy += gy * uy[i]
                e = eta[dofsd[K, a]]
                ex += gx * e
                ey += gy * e
            r0 += w * (qxx + qyy)
            r1 += w * (qxx * vx + qx * vxx + qxy * vy + qx * vyy + g * hq * ex)
            r2 += w * (qyx * vx + qy * vxx + qyy * vy + qy * vyy + g * hq * ey)
        d = 3 * dof0[K]
        b[d] = -0.5 * dt * r0
        b[d + 1] = -0.5 * dt * r1
        b[d + 2] = -0.5 * dt * r2
