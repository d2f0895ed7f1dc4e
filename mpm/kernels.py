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

__all__ = ["P2G_COLUMNS", "deposit", "deposit_momentum", "deposit_node", "flip_gather",
           "flip_set", "g2p_flip", "gradient_terms",
           "g2p_gradient", "gimp_interpolate", "interpolate", "p2g", "p2g_momentum"]

#: Columns of the nodal array returned by :func:`p2g`.
P2G_COLUMNS = ("mass", "mom_x", "mom_y", "force_x", "force_y", "area", "volume")


@numba.njit(cache=True, inline="always")
def deposit(out, i, c, x, ext):
    """Add ``x`` to node ``i``, column ``c`` in two folds (see :mod:`fem_runout.exact_sum`)."""
    hi = (x + ext[c, 0]) - ext[c, 0]
    out[i, c, 0] += hi
    x -= hi
    out[i, c, 1] += (x + ext[c, 1]) - ext[c, 1]


@numba.njit(cache=True, inline="always")
def deposit_momentum(out, i, p, w, rx, ry, mass, u, v, affine, ext):
    """Deposit particle ``p``'s momentum ``m_p (v_p + C_p r) w`` at node ``i`` (columns 0, 1)."""
    deposit(out, i, 0, mass[p] * (u[p] + (affine[0, p] * rx + affine[1, p] * ry)) * w, ext)
    deposit(out, i, 1, mass[p] * (v[p] + (affine[2, p] * rx + affine[3, p] * ry)) * w, ext)


@numba.njit(cache=True, inline="always")
def deposit_node(out, i, p, w, gx, gy, rx, ry, mass, u, v, affine, body_x, body_y, sxx, syy,
                 sxy, area, volume, ext):
    """Deposit particle ``p``'s seven P2G columns at node ``i`` (seed eqs. 33-34).

    Weight ``w``, gradient ``(gx, gy)``, ``r = x_i - x̄_p``; the order of :data:`P2G_COLUMNS`.
    """
    deposit(out, i, 0, mass[p] * w, ext)
    deposit(out, i, 1, mass[p] * (u[p] + (affine[0, p] * rx + affine[1, p] * ry)) * w, ext)
    deposit(out, i, 2, mass[p] * (v[p] + (affine[2, p] * rx + affine[3, p] * ry)) * w, ext)
    deposit(out, i, 3, body_x[p] * w + sxx[p] * gx + sxy[p] * gy, ext)
    deposit(out, i, 4, body_y[p] * w + sxy[p] * gx + syy[p] * gy, ext)
    deposit(out, i, 5, area[p] * w, ext)
    deposit(out, i, 6, volume[p] * w, ext)


@numba.njit(cache=True, inline="always")
def gradient_terms(g00, g01, g10, g11, i, vx, vy, gx, gy):
    """Add node ``i``'s velocity times its weight gradient ``(gx, gy)`` to ``∇v`` at a particle."""
    return g00 + vx[i] * gx, g01 + vx[i] * gy, g10 + vy[i] * gx, g11 + vy[i] * gy


@numba.njit(cache=True, inline="always")
def node_index(i0, j0, a, b, nx, ny):
    """Structured index of node ``(a, b)`` of a particle's 3 × 3 block (clipped to the grid)."""
    return min(j0 + b, ny) * (nx + 1) + min(i0 + a, nx)


@numba.njit(cache=True, inline="always")
def _box_index(i0, j0, a, b, nx, ny, box):
    """Position of node ``(a, b)`` of a particle's block in a box ``(row, col, rows, cols)``."""
    return (min(j0 + b, ny) - box[0]) * box[3] + min(i0 + a, nx) - box[1]


@numba.njit(cache=True, inline="always")
def _centre(w, k0, n, p):
    """Weighted centre ``Σ_a w[p, a] min(k0 + a, n)`` of a particle's nodes, in cell units.

    The GIMP weights reproduce linear functions, so this is the centre ``x̄_p`` of the
    (clipped) particle domain and ``Σ_i S_ip (x_i - x̄_p) = 0``: APIC's affine part adds no
    momentum to the grid.
    """
    return w[p, 0] * min(k0, n) + w[p, 1] * min(k0 + 1, n) + w[p, 2] * min(k0 + 2, n)


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
    for p in range(i0.size):
        xc, yc = _centre(wx, i0[p], nx, p), _centre(wy, j0[p], ny, p)
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
                i = _box_index(i0[p], j0[p], a, b, nx, ny, box)
                deposit_node(out, i, p, w, gx, gy, rx, ry, mass, u, v, affine, body_x, body_y,
                             sxx, syy, sxy, area, volume, ext)
    return out


@numba.njit(cache=True)
def p2g_momentum(basis, mass, u, v, affine, box, ext):
    """Nodal momentum ``Σ_p m_p (v_p + C_p (x_i - x̄_p)) N_i`` only, (box nodes, 2, 2) folds.

    The MUSL re-mapping; the nodes are those of ``box`` and ``affine`` as in :func:`p2g`.
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    out = np.zeros((box[2] * box[3], 2, 2))
    for p in range(i0.size):
        xc, yc = _centre(wx, i0[p], nx, p), _centre(wy, j0[p], ny, p)
        for b in range(3):
            if wy[p, b] == 0.0:
                continue
            ry = (min(j0[p] + b, ny) - yc) * dy
            for a in range(3):
                if wx[p, a] == 0.0:
                    continue
                rx = (min(i0[p] + a, nx) - xc) * dx
                w = wx[p, a] * wy[p, b]
                i = _box_index(i0[p], j0[p], a, b, nx, ny, box)
                deposit_momentum(out, i, p, w, rx, ry, mass, u, v, affine, ext)
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
                u, v, du, dv, near = flip_gather(u, v, du, dv, near, w, i, vx, vy, old_x,
                                                 old_y, stopped)
        flip_set(p, u, v, du, dv, near, keep, pu, pv, u_out, v_out)
    return u_out, v_out


@numba.njit(cache=True, inline="always")
def flip_gather(u, v, du, dv, near, w, i, vx, vy, old_x, old_y, stopped):
    """Add node ``i`` (weight ``w``) to a particle's PIC velocity, FLIP change and stop weight."""
    return (u + w * vx[i], v + w * vy[i], du + w * (vx[i] - old_x[i]),
            dv + w * (vy[i] - old_y[i]), near + w * stopped[i])


@numba.njit(cache=True, inline="always")
def flip_set(p, u, v, du, dv, near, keep, pu, pv, u_out, v_out):
    """Particle ``p``'s new velocity: FLIP share ``keep``, PIC next to stopped nodes."""
    f = 0.0 if near > 0.0 else keep
    u_out[p] = f * (pu[p] + du) + (1.0 - f) * u
    v_out[p] = f * (pv[p] + dv) + (1.0 - f) * v


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
                g00, g01, g10, g11 = gradient_terms(
                    g00, g01, g10, g11, node_index(i0[p], j0[p], a, b, nx, ny), vx, vy,
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
