"""Particle ↔ grid transfers with the point Q1 basis on any quadrilateral mesh (issue 17).

The same kernels as :mod:`mpm.kernels` and :mod:`mpm.forces` (same arguments, same returns,
same arithmetic per node), for the weights of :func:`mpm.mesh_locate.domain_basis`: particle
``p`` has the entries ``off[p] .. off[p + 1] - 1``, each a global node, ``S_ip``, ``∇S_ip``
and ``x_i - x_p`` (APIC's affine part). A node may appear in several entries of a particle
(its domain reaches the node from several cells): the sums are the same. A P2G box is a
range of global node numbers ``box = (0, first, 1, count)``: the mesh numbering sorts nodes
by ``(y, x)``, so a rank's strip of particles writes a compact range.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mpm.kernels import deposit

__all__ = ["g2p_flip", "g2p_gradient", "interpolate", "p2g", "p2g_momentum",
           "particle_forces", "transfer_bounds"]


@numba.njit(cache=True)
def p2g(basis, mass, u, v, affine, body_x, body_y, sxx, syy, sxy, area, volume, box, ext):
    """:func:`mpm.kernels.p2g` with the point basis: (box nodes, 7, 2) folds."""
    off, nodes, N, dN, rel = basis
    out = np.zeros((box[2] * box[3], 7, 2))
    for p in range(off.size - 1):
        for a in range(off[p], off[p + 1]):
            w = N[a]
            gx, gy = dN[a, 0], dN[a, 1]
            rx, ry = rel[a, 0], rel[a, 1]
            i = nodes[a] - box[1]
            deposit(out, i, 0, mass[p] * w, ext)
            deposit(out, i, 1, mass[p] * (u[p] + (affine[0, p] * rx + affine[1, p] * ry)) * w,
                     ext)
            deposit(out, i, 2, mass[p] * (v[p] + (affine[2, p] * rx + affine[3, p] * ry)) * w,
                     ext)
            deposit(out, i, 3, body_x[p] * w + sxx[p] * gx + sxy[p] * gy, ext)
            deposit(out, i, 4, body_y[p] * w + sxy[p] * gx + syy[p] * gy, ext)
            deposit(out, i, 5, area[p] * w, ext)
            deposit(out, i, 6, volume[p] * w, ext)
    return out


@numba.njit(cache=True)
def p2g_momentum(basis, mass, u, v, affine, box, ext):
    """:func:`mpm.kernels.p2g_momentum` with the point basis: (box nodes, 2, 2) folds."""
    off, nodes, N, dN, rel = basis
    out = np.zeros((box[2] * box[3], 2, 2))
    for p in range(off.size - 1):
        for a in range(off[p], off[p + 1]):
            w = N[a]
            rx, ry = rel[a, 0], rel[a, 1]
            i = nodes[a] - box[1]
            deposit(out, i, 0, mass[p] * (u[p] + (affine[0, p] * rx + affine[1, p] * ry)) * w,
                     ext)
            deposit(out, i, 1, mass[p] * (v[p] + (affine[2, p] * rx + affine[3, p] * ry)) * w,
                     ext)
    return out


@numba.njit(cache=True)
def g2p_flip(basis, vx, vy, old_x, old_y, stopped, pu, pv, keep):
    """:func:`mpm.kernels.g2p_flip` with the point basis."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    u_out, v_out = np.empty(n), np.empty(n)
    for p in range(n):
        u, v, du, dv, near = 0.0, 0.0, 0.0, 0.0, 0.0
        for a in range(off[p], off[p + 1]):
            w = N[a]
            i = nodes[a]
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
def g2p_gradient(basis, vx, vy):
    """:func:`mpm.kernels.g2p_gradient` with the point basis: (n, 2, 2)."""
    off, nodes, N, dN, rel = basis
    n = off.size - 1
    grad = np.empty((n, 2, 2))
    for p in range(n):
        g00, g01, g10, g11 = 0.0, 0.0, 0.0, 0.0
        for a in range(off[p], off[p + 1]):
            i = nodes[a]
            gx, gy = dN[a, 0], dN[a, 1]
            g00 += vx[i] * gx
            g01 += vx[i] * gy
            g10 += vy[i] * gx
            g11 += vy[i] * gy
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
    """:func:`mpm.forces.particle_forces` with the point basis (seed eqs. 26, 34, 46)."""
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
            w = N[a]
            gx += dN[a, 0] * z[i]
            gy += dN[a, 1] * z[i]
            if slope_form:
                hxx += w * hess[i, 0]
                hxy += w * hess[i, 1]
                hyy += w * hess[i, 2]
            if wb:
                big += w * still[i]
        slope = max(slope, gx * gx + gy * gy)
        grav = g
        if slope_form:
            uhu = u[p] * (hxx * u[p] + hxy * v[p]) + v[p] * (hxy * u[p] + hyy * v[p])
            cos2 = 1.0 / (1.0 + gx * gx + gy * gy)
            grav = cos2 * max(g + uhu, 0.0)
        gp[p] = grav
        if wb:
            area = volume[p] / h[p]
            weight = rho * grav * area * (h[p] - big)
            pressure = 0.5 * rho * grav * area * (h[p] * h[p] - big * big)
        else:
            weight = rho * grav * volume[p]
            pressure = 0.5 * rho * grav * volume[p] * h[p]
        out[0, p], out[1, p] = -weight * gx, -weight * gy
        out[2, p] = pressure - volume[p] * sxx[p]
        out[3, p] = pressure - volume[p] * syy[p]
        out[4, p] = -volume[p] * sxy[p]
        speed = max(speed, math.sqrt(u[p] * u[p] + v[p] * v[p]) + math.sqrt(max(grav, g) * h[p]))
    return out, gp, math.sqrt(slope), speed


@numba.njit(cache=True, inline="always")
def _bound(m, x):
    a = abs(x)
    if a != a:
        return np.inf
    return a if a > m else m


@numba.njit(cache=True)
def transfer_bounds(basis, mass, u, v, forces, area, volume):
    """:func:`mpm.forces.transfer_bounds` with the point basis; the box is a node range.

    Returns ``(15,)``: the 11 maxima, then ``-0, 0, -min(node), max(node)``.
    """
    off, nodes, N, dN, rel = basis
    b = np.zeros(15)
    b[11:] = -np.inf
    for p in range(off.size - 1):
        b[0] = _bound(b[0], mass[p])
        b[1] = _bound(b[1], mass[p] * u[p])
        b[2] = _bound(b[2], mass[p] * v[p])
        for c in range(5):
            b[3 + c] = _bound(b[3 + c], forces[c, p])
        for a in range(off[p], off[p + 1]):
            b[8] = max(b[8], abs(dN[a, 0]), abs(dN[a, 1]))
            b[13] = max(b[13], -float(nodes[a]))
            b[14] = max(b[14], float(nodes[a]))
        b[11], b[12] = max(b[11], 0.0), max(b[12], 0.0)
        b[9] = _bound(b[9], area[p])
        b[10] = _bound(b[10], volume[p])
    return b
