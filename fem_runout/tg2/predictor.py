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
#: the 2 × 2 Gauss points on the unit square (weight ¼ each)
_S = (_A, 1.0 - _A, _A, 1.0 - _A)
_T = (_A, _A, 1.0 - _A, 1.0 - _A)


@numba.njit(cache=True, inline="always")
def _coefficients(values, nodes):
    """``(f_0, f_1 - f_0, f_2 - f_0, f_0 - f_1 - f_2 + f_3)`` of ``values`` at the cell's nodes.

    The bilinear ``f(s, t) = f_0 + s (f_1 - f_0) + t (f_2 - f_0) + s t (f_0 - f_1 - f_2 + f_3)``
    in basix's node order (0, 0), (1, 0), (0, 1), (1, 1).
    """
    f0, f1, f2, f3 = values[nodes[0]], values[nodes[1]], values[nodes[2]], values[nodes[3]]
    return f0, f1 - f0, f2 - f0, (f0 - f1) - (f2 - f3)


@numba.njit(cache=True, inline="always")
def _inverse(jxs, jxt, jys, jyt):
    """Gauss weight ``¼ |det J|`` and ``J⁻ᵀ`` of ``J = [[x_s, x_t], [y_s, y_t]]``.

    Returns ``(w, a_x, b_x, a_y, b_y)``: ``∂_x = a_x ∂_s + b_x ∂_t``, ``∂_y = a_y ∂_s + b_y ∂_t``.
    """
    det = jxs * jyt - jxt * jys
    inv = 1.0 / det
    return 0.25 * abs(det), jyt * inv, -jys * inv, -jxt * inv, jxs * inv


@numba.njit(cache=True)
def predictor_cells(cells, cell_nodes, coords, h, hu, hv, ux, uy, eta, dofsd, G, dofs0,
                    g_const, dt, dof0, b):
    """``b[3 dof0[K] + c] = b_K[c]`` for the cells ``cells`` (see the module docstring).

    Every field is written in the bilinear form of :func:`_coefficients`; at each Gauss point
    its value and reference derivatives ``(∂_s f, ∂_t f) = (f_1 - f_0 + t c, f_2 - f_0 + s c)``
    are mapped by the inverse Jacobian of the cell's bilinear map (``∇f = J⁻ᵀ ∇_ref f``).

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
    x = coords[:, 0]
    y = coords[:, 1]
    for k in range(cells.shape[0]):
        K = cells[k]
        nodes = cell_nodes[K]
        x0, xs, xt, xc = _coefficients(x, nodes)
        y0, ys, yt, yc = _coefficients(y, nodes)
        h0, hs, ht, hc = _coefficients(h, nodes)
        p0, ps, pt, pc = _coefficients(hu, nodes)
        q0, qs, qt, qc = _coefficients(hv, nodes)
        u0, us, ut, uc = _coefficients(ux, nodes)
        v0, vs, vt, vc = _coefficients(uy, nodes)
        e0, es, et, ec = _coefficients(eta, dofsd[K])
        g = g_const if g_const > 0.0 else G[dofs0[K]]
        r0 = r1 = r2 = 0.0
        # a parallelogram's Jacobian is constant: computed once, the same numbers as per
        # point (``x_s + t · 0`` is ``x_s`` exactly), so this changes the cost, not the result
        parallelogram = xc == 0.0 and yc == 0.0
        w, ax, bx, ay, by = _inverse(xs, xt, ys, yt)
        for i in range(4):
            s, t = _S[i], _T[i]
            st = s * t
            if not parallelogram:
                w, ax, bx, ay, by = _inverse(xs + t * xc, xt + s * xc, ys + t * yc, yt + s * yc)
            hq = h0 + s * hs + t * ht + st * hc
            qx = p0 + s * ps + t * pt + st * pc
            qy = q0 + s * qs + t * qt + st * qc
            vx = u0 + s * us + t * ut + st * uc
            vy = v0 + s * vs + t * vt + st * vc
            p_s, p_t = ps + t * pc, pt + s * pc
            q_s, q_t = qs + t * qc, qt + s * qc
            qxx, qxy = ax * p_s + bx * p_t, ay * p_s + by * p_t
            qyx, qyy = ax * q_s + bx * q_t, ay * q_s + by * q_t
            vxx = ax * (us + t * uc) + bx * (ut + s * uc)
            vyy = ay * (vs + t * vc) + by * (vt + s * vc)
            e_s, e_t = es + t * ec, et + s * ec
            ex, ey = ax * e_s + bx * e_t, ay * e_s + by * e_t
            r0 += w * (qxx + qyy)
            r1 += w * (qxx * vx + qx * vxx + qxy * vy + qx * vyy + g * hq * ex)
            r2 += w * (qyx * vx + qy * vxx + qyy * vy + qy * vyy + g * hq * ey)
        d = 3 * dof0[K]
        b[d] = -0.5 * dt * r0
        b[d + 1] = -0.5 * dt * r1
        b[d + 2] = -0.5 * dt * r2
