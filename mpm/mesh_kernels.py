"""Particle ↔ grid transfers with the point Q1 basis on any quadrilateral mesh (issue 17).

The same kernels as :mod:`mpm.kernels` and :mod:`mpm.forces` (same arguments, same returns,
same arithmetic per node), for the weights of :func:`mpm.mesh_weights.domain_basis`: particle
``p`` has the entries ``off[p] .. off[p + 1] - 1``, each a global node, ``S_ip``, ``∇S_ip``
and ``x_i - x_p`` (APIC's affine part), one entry per node the particle's domain reaches.
A P2G box is a range of global node numbers ``box = (0, first, 1, count)``: the mesh
numbering sorts nodes by ``(y, x)``, so a rank's strip of particles writes a compact range.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fem_runout.exact_fold import fold
from mpm.forces import NO_BOUNDS, ZERO3, bed_terms, particle_bounds, particle_force, put_bounds
from mpm.kernels import flip_gather, flip_set, gradient_terms, momentum_columns, node_columns

__all__ = ["g2p_flip", "g2p_gradient", "interpolate", "p2g", "p2g_momentum",
           "particle_forces", "transfer_bounds"]


@numba.njit(cache=True)
def p2g(basis, mass, u, v, affine, body_x, body_y, sxx, syy, sxy, area, volume, box, ext):
    """:func:`mpm.kernels.p2g` with the mesh's domain weights: (box nodes, 7, 2) folds."""
    off, nodes, N, dN, rel = basis
    out = np.zeros((box[2] * box[3], 7, 2))
    for p in range(off.size - 1):
        for a in range(off[p], off[p + 1]):
            w = N[a]
            gx, gy = dN[a, 0], dN[a, 1]
            rx, ry = rel[a, 0], rel[a, 1]
            i = nodes[a] - box[1]
            vals = node_columns(w, gx, gy, rx, ry, mass[p], u[p], v[p], affine[0, p],
                                affine[1, p], affine[2, p], affine[3, p], body_x[p], body_y[p],
                                sxx[p], syy[p], sxy[p], area[p], volume[p])
            for c in range(7):
                hi, lo = fold(vals[c], ext[c, 0], ext[c, 1])
                out[i, c, 0] += hi
                out[i, c, 1] += lo
    return out


@numba.njit(cache=True)
def p2g_momentum(basis, mass, u, v, affine, box, ext):
    """:func:`mpm.kernels.p2g_momentum` with the mesh's domain weights: (box nodes, 2, 2) folds."""
    off, nodes, N, dN, rel = basis
    out = np.zeros((box[2] * box[3], 2, 2))
    for p in range(off.size - 1):
        for a in range(off[p], off[p + 1]):
            w = N[a]
            rx, ry = rel[a, 0], rel[a, 1]
            i = nodes[a] - box[1]
            mx, my = momentum_columns(w, rx, ry, mass[p], u[p], v[p], affine[0, p], affine[1, p],
                                      affine[2, p], affine[3, p])
            for c, x in ((0, mx), (1, my)):
                hi, lo = fold(x, ext[c, 0], ext[c, 1])
                out[i, c, 0] += hi
                out[i, c, 1] += lo
    return out


@numba.njit(cache=True)
def g2p_flip(basis, vx, vy, old_x, old_y, stopped, pu, pv, keep):
    """:func:`mpm.kernels.g2p_flip` with the mesh's domain weights."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    u_out, v_out = np.empty(n), np.empty(n)
    for p in range(n):
        u, v, du, dv, near = 0.0, 0.0, 0.0, 0.0, 0.0
        for a in range(off[p], off[p + 1]):
            i = nodes[a]
            u, v, du, dv, near = flip_gather(u, v, du, dv, near, N[a], vx[i], vy[i], old_x[i],
                                             old_y[i], stopped[i])
        u_out[p], v_out[p] = flip_set(u, v, du, dv, near, keep, pu[p], pv[p])
    return u_out, v_out


@numba.njit(cache=True)
def g2p_gradient(basis, vx, vy):
    """:func:`mpm.kernels.g2p_gradient` with the mesh's domain weights: (n, 2, 2)."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    grad = np.empty((n, 2, 2))
    for p in range(n):
        g00, g01, g10, g11 = 0.0, 0.0, 0.0, 0.0
        for a in range(off[p], off[p + 1]):
            i = nodes[a]
            g00, g01, g10, g11 = gradient_terms(g00, g01, g10, g11, vx[i], vy[i], dN[a, 0],
                                                dN[a, 1])
        grad[p, 0, 0], grad[p, 0, 1], grad[p, 1, 0], grad[p, 1, 1] = g00, g01, g10, g11
    return grad


@numba.njit(cache=True)
def interpolate(basis, values):
    """``Σ_i values_i N_i(x_p)`` at the particles (:func:`mpm.kernels.gimp_interpolate`)."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    out = np.empty(n)
    for p in range(n):
        acc = 0.0
        for a in range(off[p], off[p + 1]):
            acc += N[a] * values[nodes[a]]
        out[p] = acc
    return out


@numba.njit(cache=True)
def particle_forces(basis, z, hess, still, rho, g, volume, h, u, v, sxx, syy, sxy):
    """:func:`mpm.forces.particle_forces` with the mesh's domain weights (seed eqs. 26, 34, 46)."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    out = np.empty((5, n))
    gp = np.empty(n)
    slope_form, wb = hess.shape[0] > 0, still.size > 0
    slope, speed = 0.0, 0.0
    for p in range(n):
        gx, gy, hxx, hxy, hyy, big = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for a in range(off[p], off[p + 1]):
            i = nodes[a]
            h0, h1, h2 = (hess[i, 0], hess[i, 1], hess[i, 2]) if slope_form else ZERO3
            gx, gy, hxx, hxy, hyy, big = bed_terms(gx, gy, hxx, hxy, hyy, big, N[a], dN[a, 0],
                                                   dN[a, 1], z[i], h0, h1, h2,
                                                   still[i] if wb else 0.0, slope_form, wb)
        slope = max(slope, gx * gx + gy * gy)
        gp[p], out[0, p], out[1, p], out[2, p], out[3, p], out[4, p], s = particle_force(
            gx, gy, hxx, hxy, hyy, big, slope_form, wb, rho, g, volume[p], h[p], u[p], v[p],
            sxx[p], syy[p], sxy[p])
        speed = max(speed, s)
    return out, gp, math.sqrt(slope), speed


@numba.njit(cache=True)
def transfer_bounds(basis, mass, u, v, forces, area, volume):
    """:func:`mpm.forces.transfer_bounds` with the mesh's domain weights; the box is a node range.

    Returns ``(15,)``: the 11 maxima, then ``-0, 0, -min(node), max(node)``.
    """
    off, nodes, N, dN, rel = basis
    b = np.zeros(15)
    b[11:] = -np.inf
    t = NO_BOUNDS
    for p in range(off.size - 1):
        t = particle_bounds(t, mass[p], u[p], v[p], forces[0, p], forces[1, p], forces[2, p],
                            forces[3, p], forces[4, p], area[p], volume[p])
        for a in range(off[p], off[p + 1]):
            b[8] = max(b[8], abs(dN[a, 0]), abs(dN[a, 1]))
            b[13] = max(b[13], -float(nodes[a]))
            b[14] = max(b[14], float(nodes[a]))
        b[11], b[12] = max(b[11], 0.0), max(b[12], 0.0)
    put_bounds(b, t)
    return b
