"""Numba kernels of the particle ↔ grid transfers (no Python loop over particles).

The step kernels take the GIMP basis in factored form (:class:`mpm.gimp.GimpBasis`: the
``3 × 3`` nodes of a particle, weights ``S = wx_a wy_b``, gradients ``(dwx_a wy_b,
wx_a dwy_b)``) and form the products as they go, with the same arithmetic as the expanded
arrays (the same bits). ``p2g`` scatters the particle mass, momentum, area, volume sums and
forces of seed eqs. 33-34 to those nodes; ``g2p_flip`` gathers the nodal velocity (seed eq. 38
with FLIP) and ``g2p_gradient`` its gradient (for the strain increment of seed eq. 40). A
factor that is zero with its derivative (a node outside the particle's domain) is skipped:
adding exact zeros changes no bit, and a domain inside one cell has four non-zero weights of
nine. :func:`interpolate` is the expanded form (any nodes per particle) for seeding.
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.exact_fold import fold

__all__ = ["P2G_COLUMNS", "flip_gather", "flip_set", "g2p_flip", "g2p_gradient",
           "gimp_interpolate", "gradient_terms", "interpolate", "momentum_columns",
           "node_columns", "p2g", "p2g_momentum"]

#: Columns of the nodal array returned by :func:`p2g`.
P2G_COLUMNS = ("mass", "mom_x", "mom_y", "force_x", "force_y", "area", "volume")


@numba.njit(cache=True, inline="always")
def node_columns(w, gx, gy, rx, ry, m, u, v, c0, c1, c2, c3, bx, by, sxx, syy, sxy, area,
                 volume):
    """Return a particle's seven P2G columns at a node (seed eqs. 33-34), as P2G_COLUMNS.

    Weight ``w``, gradient ``(gx, gy)``, ``r = x_i - x̄_p``; the particle's mass, velocity,
    affine velocity ``C``, body force, force tensor, area and volume.
    """
    return (m * w, m * (u + (c0 * rx + c1 * ry)) * w, m * (v + (c2 * rx + c3 * ry)) * w,
            bx * w + sxx * gx + sxy * gy, by * w + sxy * gx + syy * gy, area * w, volume * w)


@numba.njit(cache=True, inline="always")
def momentum_columns(w, rx, ry, m, u, v, c0, c1, c2, c3):
    """Return a particle's momentum ``m_p (v_p + C_p r) w`` at a node (p2g's columns 1, 2)."""
    return m * (u + (c0 * rx + c1 * ry)) * w, m * (v + (c2 * rx + c3 * ry)) * w


@numba.njit(cache=True, inline="always")
def gradient_terms(g00, g01, g10, g11, vx, vy, gx, gy):
    """Add a node's velocity ``(vx, vy)`` times its weight gradient ``(gx, gy)`` to ``∇v``."""
    return g00 + vx * gx, g01 + vx * gy, g10 + vy * gx, g11 + vy * gy


@numba.njit(cache=True, inline="always")
def node_index(i0, j0, a, b, nx, ny):
    """Structured index of node ``(a, b)`` of a particle's 3 × 3 block (clipped to the grid)."""
    return min(j0 + b, ny) * (nx + 1) + min(i0 + a, nx)


@numba.njit(cache=True, inline="always")
def _centre(w0, w1, w2, k0, n):
    """Weighted centre ``Σ_a w_a min(k0 + a, n)`` of a particle's nodes, in cell units.

    The GIMP weights reproduce linear functions, so this is the centre ``x̄_p`` of the
    (clipped) particle domain and ``Σ_i S_ip (x_i - x̄_p) = 0``: APIC's affine part adds no
    momentum to the grid.
    """
    return w0 * min(k0, n) + w1 * min(k0 + 1, n) + w2 * min(k0 + 2, n)


@numba.njit(cache=True)
def p2g(basis, mass, u, v, affine, body_x, body_y, sxx, syy, sxy,
        area, volume, box, ext):
    """Particle-to-grid sums (seed eqs. 33-34), as exact two-fold partial sums.

    Args:
        basis: The factored GIMP basis, :attr:`mpm.gimp.GimpBasis.arrays`.
        mass: ``m_p`` [kg].
        u: x-velocity [m/s].
        v: y-velocity [m/s].
        affine: (4, n) affine velocity ``C_xx, C_xy, C_yx, C_yy`` of APIC [1/s]: node ``i``
            receives ``m_p S_ip (v_p + C_p (x_i - x̄_p))`` (zeros: the seed's eq. 33).
        body_x: x-force per particle multiplying ``N_i`` (gravity of eq. 34 or 46) [N].
        body_y: y-force per particle multiplying ``N_i`` [N].
        sxx: xx entry of the particle force tensor ``-V_p σ^∇_p`` [N m] (× ``∇N_i``).
        syy: yy entry of the force tensor [N m].
        sxy: xy entry of the force tensor [N m].
        area: ``A_p`` [m²].
        volume: ``V_p`` [m³].
        box: ``(row, column, rows, columns)`` of the box of nodes written (every particle's
            nodes lie in it; :class:`mpm.exchange.Box`), row-major.
        ext: (7, 2) extractors of the two folds per column
            (:func:`fem_runout.exact_sum.extractors`).

    Returns:
        (box nodes, 7, 2) fold sums of the box's nodes in the order of :data:`P2G_COLUMNS`;
        their sum over ranks and folds (:class:`mpm.exchange.FoldExchange`) does not depend
        on the order.
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    out = np.zeros((box[2] * box[3], 7, 2))
    r0, c0, cols = box[0], box[1], box[3]
    for p in range(i0.size):
        xc = _centre(wx[p, 0], wx[p, 1], wx[p, 2], i0[p], nx)
        yc = _centre(wy[p, 0], wy[p, 1], wy[p, 2], j0[p], ny)
        for b in range(3):
            if wy[p, b] == 0.0 and dwy[p, b] == 0.0:
                continue
            ry = (min(j0[p] + b, ny) - yc) * dy
            for a in range(3):
                if wx[p, a] == 0.0 and dwx[p, a] == 0.0:
                    continue
                rx = (min(i0[p] + a, nx) - xc) * dx
                w = wx[p, a] * wy[p, b]
                gx, gy = dwx[p, a] * wy[p, b], wx[p, a] * dwy[p, b]
                i = (min(j0[p] + b, ny) - r0) * cols + min(i0[p] + a, nx) - c0
                vals = node_columns(w, gx, gy, rx, ry, mass[p], u[p], v[p], affine[0, p],
                                    affine[1, p], affine[2, p], affine[3, p], body_x[p],
                                    body_y[p], sxx[p], syy[p], sxy[p], area[p], volume[p])
                for c in range(7):
                    hi, lo = fold(vals[c], ext[c, 0], ext[c, 1])
                    out[i, c, 0] += hi
                    out[i, c, 1] += lo
    return out


@numba.njit(cache=True)
def p2g_momentum(basis, mass, u, v, affine, box, ext):
    """Nodal momentum ``Σ_p m_p (v_p + C_p (x_i - x̄_p)) N_i`` only, (box nodes, 2, 2) folds.

    The MUSL re-mapping; the nodes are those of ``box`` and ``affine`` as in :func:`p2g`.
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    out = np.zeros((box[2] * box[3], 2, 2))
    r0, c0, cols = box[0], box[1], box[3]
    for p in range(i0.size):
        xc = _centre(wx[p, 0], wx[p, 1], wx[p, 2], i0[p], nx)
        yc = _centre(wy[p, 0], wy[p, 1], wy[p, 2], j0[p], ny)
        for b in range(3):
            if wy[p, b] == 0.0:
                continue
            ry = (min(j0[p] + b, ny) - yc) * dy
            for a in range(3):
                if wx[p, a] == 0.0:
                    continue
                rx = (min(i0[p] + a, nx) - xc) * dx
                w = wx[p, a] * wy[p, b]
                i = (min(j0[p] + b, ny) - r0) * cols + min(i0[p] + a, nx) - c0
                mx, my = momentum_columns(w, rx, ry, mass[p], u[p], v[p], affine[0, p],
                                          affine[1, p], affine[2, p], affine[3, p])
                for c, x in ((0, mx), (1, my)):
                    hi, lo = fold(x, ext[c, 0], ext[c, 1])
                    out[i, c, 0] += hi
                    out[i, c, 1] += lo
    return out


@numba.njit(cache=True)
def g2p_flip(basis, vx, vy, old_x, old_y, stopped, pu, pv,
             keep):
    """FLIP/PIC blend of the grid-to-particle velocity (seed eq. 38 with FLIP), one pass.

    ``v_p ← f (v_p + Σ_i (v_i - v_i^old) N_i) + (1 - f) Σ_i v_i N_i`` with ``f = 0`` where
    ``Σ_i stopped_i N_i > 0`` (next to a node friction stopped) and ``f = keep`` elsewhere
    (``keep = 0``: PIC, seed eq. 38).

    Args:
        basis: The factored GIMP basis, :attr:`mpm.gimp.GimpBasis.arrays`.
        vx: Nodal x-velocity at the end of the step.
        vy: Nodal y-velocity at the end of the step.
        old_x: Nodal x-velocity mapped from the particles at the start of the step.
        old_y: Nodal y-velocity mapped from the particles at the start of the step.
        stopped: 1 at nodes where friction stopped the flow, else 0.
        pu: Particle x-velocity at the start of the step.
        pv: Particle y-velocity at the start of the step.
        keep: FLIP fraction ``f`` away from stopped nodes.

    Returns:
        ``(u, v)``: the new particle velocity.
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    n = i0.size
    u_out = np.empty(n)
    v_out = np.empty(n)
    for p in range(n):
        u, v, du, dv, near = 0.0, 0.0, 0.0, 0.0, 0.0
        for b in range(3):
            if wy[p, b] == 0.0:
                continue
            for a in range(3):
                if wx[p, a] == 0.0:
                    continue
                w = wx[p, a] * wy[p, b]
                i = node_index(i0[p], j0[p], a, b, nx, ny)
                u, v, du, dv, near = flip_gather(u, v, du, dv, near, w, vx[i], vy[i], old_x[i],
                                                 old_y[i], stopped[i])
        u_out[p], v_out[p] = flip_set(u, v, du, dv, near, keep, pu[p], pv[p])
    return u_out, v_out


@numba.njit(cache=True, inline="always")
def flip_gather(u, v, du, dv, near, w, vx, vy, old_x, old_y, stopped):
    """Add a node (weight ``w``, its values) to a particle's PIC velocity, FLIP change, stop."""
    return (u + w * vx, v + w * vy, du + w * (vx - old_x), dv + w * (vy - old_y),
            near + w * stopped)


@numba.njit(cache=True, inline="always")
def flip_set(u, v, du, dv, near, keep, pu, pv):
    """Return a particle's new velocity: FLIP share ``keep``, PIC next to stopped nodes."""
    f = 0.0 if near > 0.0 else keep
    return f * (pu + du) + (1.0 - f) * u, f * (pv + dv) + (1.0 - f) * v


@numba.njit(cache=True)
def g2p_gradient(basis, vx, vy):
    """Velocity gradient ``grad[p, a, b] = Σ_i v_{i,a} ∂_b N_i(x_p)`` at the particles."""
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    n = i0.size
    grad = np.empty((n, 2, 2))
    for p in range(n):
        g00, g01, g10, g11 = 0.0, 0.0, 0.0, 0.0
        for b in range(3):
            if wy[p, b] == 0.0 and dwy[p, b] == 0.0:
                continue
            for a in range(3):
                if wx[p, a] == 0.0 and dwx[p, a] == 0.0:
                    continue
                i = node_index(i0[p], j0[p], a, b, nx, ny)
                g00, g01, g10, g11 = gradient_terms(g00, g01, g10, g11, vx[i], vy[i],
                                                    dwx[p, a] * wy[p, b], wx[p, a] * dwy[p, b])
        grad[p, 0, 0], grad[p, 0, 1], grad[p, 1, 0], grad[p, 1, 1] = g00, g01, g10, g11
    return grad


@numba.njit(cache=True)
def gimp_interpolate(basis, values):
    """Q1 (GIMP) interpolant ``Σ_i values_i S_ip`` at the particles."""
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    n = i0.size
    out = np.empty(n)
    for p in range(n):
        acc = 0.0
        for b in range(3):
            if wy[p, b] == 0.0:
                continue
            for a in range(3):
                if wx[p, a] == 0.0:
                    continue
                acc += wx[p, a] * wy[p, b] * values[node_index(i0[p], j0[p], a, b, nx, ny)]
        out[p] = acc
    return out


@numba.njit(cache=True)
def interpolate(nodes, N, values):
    """Q1 interpolant ``Σ_i values_i N_i(x_p)`` (fixed summation order: bitwise reproducible)."""
    n = nodes.shape[0]
    out = np.zeros(n)
    for p in range(n):
        acc = 0.0
        for k in range(nodes.shape[1]):
            acc += N[p, k] * values[nodes[p, k]]
        out[p] = acc
    return out
