"""Numba kernels of the particle ↔ grid transfers (no Python loop over particles).

Every kernel takes per-particle node indices, weights and weight gradients with any number
of nodes per particle (4 for point values in a cell, 9 for the GIMP domains of
:mod:`mpm.gimp`). ``p2g`` scatters the particle mass, momentum, area, volume sums and forces
of seed eqs. 33-34 to those nodes; ``g2p`` gathers the nodal velocity (seed eq. 38) and its
gradient (for the strain increment of seed eq. 40). The scatters skip nodes with a zero
weight and gradient: the sums get the same bits (adding an exact zero), for about half the
work (a domain inside one cell has four non-zero weights of nine); the gathers stay
branch-free (faster as they are).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["P2G_COLUMNS", "g2p", "g2p_flip", "g2p_gradient", "interpolate", "interpolate_gradient",
           "p2g", "p2g_momentum"]

#: Columns of the nodal array returned by :func:`p2g`.
P2G_COLUMNS = ("mass", "mom_x", "mom_y", "force_x", "force_y", "area", "volume")


@numba.njit(cache=True, inline="always")
def _deposit(out, i, c, x, ext):
    """Add ``x`` to node ``i``, column ``c`` in two folds (see :mod:`fem_runout.exact_sum`)."""
    hi = (x + ext[c, 0]) - ext[c, 0]
    out[i, c, 0] += hi
    x -= hi
    out[i, c, 1] += (x + ext[c, 1]) - ext[c, 1]


@numba.njit(cache=True)
def p2g(nodes, N, dN, mass, u, v, body_x, body_y, sxx, syy, sxy, area, volume, offset, n_nodes,
        ext):
    """Particle-to-grid sums (seed eqs. 33-34), as exact two-fold partial sums.

    Args:
        nodes: (n, k) node indices of each particle.
        N: (n, k) weights at the particles.
        dN: (n, k, 2) weight gradients at the particles.
        mass: ``m_p`` [kg].
        u: x-velocity [m/s].
        v: y-velocity [m/s].
        body_x: x-force per particle multiplying ``N_i`` (gravity of eq. 34 or 46) [N].
        body_y: y-force per particle multiplying ``N_i`` [N].
        sxx: xx entry of the particle force tensor ``-V_p σ^∇_p`` [N m] (× ``∇N_i``).
        syy: yy entry of the force tensor [N m].
        sxy: xy entry of the force tensor [N m].
        area: ``A_p`` [m²].
        volume: ``V_p`` [m³].
        offset: First node of the window written (node ``i`` goes to row ``i - offset``).
        n_nodes: Number of nodes of the window (every particle's nodes lie in it).
        ext: (7, 2) extractors of the two folds per column
            (:func:`fem_runout.exact_sum.extractors`).

    Returns:
        (n_nodes, 7, 2) fold sums of the window's nodes in the order of :data:`P2G_COLUMNS`;
        their sum over ranks and folds (:meth:`mpm.nodal.NodalGrid.exact_sum`) does not depend
        on the order.
    """
    out = np.zeros((n_nodes, 7, 2))
    for p in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            w = N[p, k]
            gx, gy = dN[p, k, 0], dN[p, k, 1]
            if w == 0.0 and gx == 0.0 and gy == 0.0:
                continue  # a node outside the domain: adding zeros changes no bit
            i = nodes[p, k] - offset
            _deposit(out, i, 0, mass[p] * w, ext)
            _deposit(out, i, 1, mass[p] * u[p] * w, ext)
            _deposit(out, i, 2, mass[p] * v[p] * w, ext)
            _deposit(out, i, 3, body_x[p] * w + sxx[p] * gx + sxy[p] * gy, ext)
            _deposit(out, i, 4, body_y[p] * w + sxy[p] * gx + syy[p] * gy, ext)
            _deposit(out, i, 5, area[p] * w, ext)
            _deposit(out, i, 6, volume[p] * w, ext)
    return out


@numba.njit(cache=True)
def p2g_momentum(nodes, N, mass, u, v, offset, n_nodes, ext):
    """Nodal momentum ``Σ_p m_p v_p N_i`` only, (n_nodes, 2, 2) folds (the MUSL re-mapping).

    Node ``i`` goes to row ``i - offset`` of a window of ``n_nodes`` nodes (see :func:`p2g`).
    """
    out = np.zeros((n_nodes, 2, 2))
    for p in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            if N[p, k] == 0.0:
                continue
            i = nodes[p, k] - offset
            _deposit(out, i, 0, mass[p] * u[p] * N[p, k], ext)
            _deposit(out, i, 1, mass[p] * v[p] * N[p, k], ext)
    return out


@numba.njit(cache=True)
def g2p(nodes, N, dN, vx, vy):
    """Grid-to-particle velocity (seed eq. 38) and velocity gradient.

    Args:
        nodes: (n, k) node indices of each particle.
        N: (n, k) weights at the particles.
        dN: (n, k, 2) weight gradients at the particles.
        vx: Nodal x-velocity.
        vy: Nodal y-velocity.

    Returns:
        ``(u, v, grad)`` with ``grad[p, a, b] = Σ_i v_{i,a} ∂_b N_i(x_p)``.
    """
    n = nodes.shape[0]
    u = np.zeros(n)
    v = np.zeros(n)
    grad = np.zeros((n, 2, 2))
    for p in range(n):
        for k in range(nodes.shape[1]):
            i = nodes[p, k]
            u[p] += N[p, k] * vx[i]
            v[p] += N[p, k] * vy[i]
            for b in range(2):
                grad[p, 0, b] += vx[i] * dN[p, k, b]
                grad[p, 1, b] += vy[i] * dN[p, k, b]
    return u, v, grad


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


@numba.njit(cache=True)
def interpolate_gradient(nodes, dN, values):
    """Gradient of the Q1 interpolant at the particles, shape (n, 2)."""
    n = nodes.shape[0]
    out = np.zeros((n, 2))
    for p in range(n):
        for k in range(nodes.shape[1]):
            out[p, 0] += dN[p, k, 0] * values[nodes[p, k]]
            out[p, 1] += dN[p, k, 1] * values[nodes[p, k]]
    return out


@numba.njit(cache=True)
def g2p_flip(nodes, N, vx, vy, old_x, old_y, stopped, pu, pv, keep):
    """FLIP/PIC blend of the grid-to-particle velocity (seed eq. 38 with FLIP), one pass.

    ``v_p ← f (v_p + Σ_i (v_i - v_i^old) N_i) + (1 - f) Σ_i v_i N_i`` with ``f = 0`` where
    ``Σ_i stopped_i N_i > 0`` (next to a node friction stopped) and ``f = keep`` elsewhere.

    Args:
        nodes: (n, k) node indices of each particle.
        N: (n, k) weights at the particles.
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
    n = nodes.shape[0]
    u_out = np.empty(n)
    v_out = np.empty(n)
    for p in range(n):
        u = 0.0
        v = 0.0
        du = 0.0
        dv = 0.0
        near = 0.0
        for k in range(nodes.shape[1]):
            w = N[p, k]
            if w == 0.0:
                continue
            i = nodes[p, k]
            u += w * vx[i]
            v += w * vy[i]
            du += w * (vx[i] - old_x[i])
            dv += w * (vy[i] - old_y[i])
            near += w * stopped[i]
        f = 0.0 if near > 0.0 else keep
        u_out[p] = f * (pu[p] + du) + (1.0 - f) * u
        v_out[p] = f * (pv[p] + dv) + (1.0 - f) * v
    return u_out, v_out


@numba.njit(cache=True)
def g2p_gradient(nodes, dN, vx, vy):
    """Velocity gradient ``grad[p, a, b] = Σ_i v_{i,a} ∂_b N_i(x_p)`` at the particles."""
    n = nodes.shape[0]
    grad = np.zeros((n, 2, 2))
    for p in range(n):
        for k in range(nodes.shape[1]):
            i = nodes[p, k]
            for b in range(2):
                grad[p, 0, b] += vx[i] * dN[p, k, b]
                grad[p, 1, b] += vy[i] * dN[p, k, b]
    return grad
