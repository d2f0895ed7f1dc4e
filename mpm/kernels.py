"""Numba kernels of the particle ↔ grid transfers (no Python loop over particles).

Every kernel takes per-particle node indices, weights and weight gradients with any number
of nodes per particle (4 for point values in a cell, 9 for the GIMP domains of
:mod:`mpm.gimp`). ``p2g`` scatters the particle mass, momentum, area, volume sums and forces
of seed eqs. 33-34 to those nodes; ``g2p`` gathers the nodal velocity (seed eq. 38) and
its gradient (for the strain increment of seed eq. 40).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["P2G_COLUMNS", "g2p", "interpolate", "interpolate_gradient", "p2g", "p2g_momentum"]

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
def p2g(nodes, N, dN, mass, u, v, body_x, body_y, sxx, syy, sxy, area, volume, n_nodes, ext):
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
        n_nodes: Number of nodes.
        ext: (7, 2) extractors of the two folds per column
            (:func:`fem_runout.exact_sum.extractors`).

    Returns:
        (n_nodes, 7, 2) fold sums in the order of :data:`P2G_COLUMNS`; their sum over ranks
        and folds (:meth:`mpm.nodal.NodalGrid.exact_sum`) does not depend on the order.
    """
    out = np.zeros((n_nodes, 7, 2))
    for p in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            i = nodes[p, k]
            w = N[p, k]
            gx, gy = dN[p, k, 0], dN[p, k, 1]
            _deposit(out, i, 0, mass[p] * w, ext)
            _deposit(out, i, 1, mass[p] * u[p] * w, ext)
            _deposit(out, i, 2, mass[p] * v[p] * w, ext)
            _deposit(out, i, 3, body_x[p] * w + sxx[p] * gx + sxy[p] * gy, ext)
            _deposit(out, i, 4, body_y[p] * w + sxy[p] * gx + syy[p] * gy, ext)
            _deposit(out, i, 5, area[p] * w, ext)
            _deposit(out, i, 6, volume[p] * w, ext)
    return out


@numba.njit(cache=True)
def p2g_momentum(nodes, N, mass, u, v, n_nodes, ext):
    """Nodal momentum ``Σ_p m_p v_p N_i`` only, (n_nodes, 2, 2) folds (the MUSL re-mapping)."""
    out = np.zeros((n_nodes, 2, 2))
    for p in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            i = nodes[p, k]
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
