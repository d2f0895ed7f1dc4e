"""The per-particle forces of one step in one pass (numba): seed eqs. 26, 34 and 46.

:func:`particle_forces` interpolates the bed gradient (and, in the slope-consistent form, its
Hessian) at the particles and returns the body force (× ``N_i``) and the force tensor
``-V_p σ^∇_p`` (× ``∇N_i``) that :func:`mpm.kernels.p2g` scatters, with the bounds that the
exact sums (:mod:`fem_runout.exact_sum`) and the step limit need. The arithmetic is the one
of the former array expressions, in the same order, except that lengths are ``sqrt(x² + y²)``
(``hypot`` cost 14 ns per call, 70 % of the pass).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mpm.kernels import node_index

#: The Hessian of a node in the seed's form (not used there).
ZERO3 = (0.0, 0.0, 0.0)

__all__ = ["NO_BOUNDS", "ZERO3", "bed_terms", "particle_bounds", "particle_force",
           "particle_forces", "put_bounds", "running_bound", "transfer_bounds"]


@numba.njit(cache=True)
def particle_forces(basis, z, hess, still, rho, g, volume, h,
                    u, v, sxx, syy, sxy):
    """Body force and force tensor per particle (seed eqs. 26, 34; eq. 46 with ``still``).

    Args:
        basis: The factored GIMP basis, :attr:`mpm.gimp.GimpBasis.arrays`.
        z: Nodal elevation.
        hess: (n_nodes, 3) nodal ``(Z_xx, Z_xy, Z_yy)`` for the slope-consistent form, where
            ``G_p = cos²θ max(g + u·H·u, 0)`` replaces ``g``; (0, 3) for the seed's form.
        still: Nodal still-water depth ``H`` (well-balanced eq. 46), or an empty array.
        rho: Density [kg/m³].
        g: Gravity [m/s²].
        volume: ``V_p`` [m³].
        h: Depth [m].
        u: x-velocity [m/s].
        v: y-velocity [m/s].
        sxx: xx stress [Pa m].
        syy: yy stress [Pa m].
        sxy: xy stress [Pa m].

    Returns:
        ``(out, gp, slope, speed)``: (5, n) body x, body y and tensor xx, yy, xy; the
        gravity ``G_p`` (``g`` in the seed's form); the largest bed slope ``|∇Z|`` and the
        largest wave speed ``|v_p| + sqrt(max(G_p, g) h_p)`` over the particles.
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    n = i0.size
    out = np.empty((5, n))
    gp = np.empty(n)
    slope_form, wb = hess.shape[0] > 0, still.size > 0
    slope, speed = 0.0, 0.0
    for p in range(n):
        gx, gy, hxx, hxy, hyy, big = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for b in range(3):
            if wy[p, b] == 0.0 and dwy[p, b] == 0.0:
                continue
            for a in range(3):
                if wx[p, a] == 0.0 and dwx[p, a] == 0.0:
                    continue
                i = node_index(i0[p], j0[p], a, b, nx, ny)
                h0, h1, h2 = (hess[i, 0], hess[i, 1], hess[i, 2]) if slope_form else ZERO3
                gx, gy, hxx, hxy, hyy, big = bed_terms(
                    gx, gy, hxx, hxy, hyy, big, wx[p, a] * wy[p, b], dwx[p, a] * wy[p, b],
                    wx[p, a] * dwy[p, b], z[i], h0, h1, h2, still[i] if wb else 0.0, slope_form,
                    wb)
        slope = max(slope, gx * gx + gy * gy)  # squared: one sqrt at the end
        gp[p], out[0, p], out[1, p], out[2, p], out[3, p], out[4, p], s = particle_force(
            gx, gy, hxx, hxy, hyy, big, slope_form, wb, rho, g, volume[p], h[p], u[p], v[p],
            sxx[p], syy[p], sxy[p])
        speed = max(speed, s)
    return out, gp, math.sqrt(slope), speed


@numba.njit(cache=True, inline="always")
def bed_terms(gx, gy, hxx, hxy, hyy, big, w, wx, wy, z, h0, h1, h2, still, slope_form, wb):
    """Add one node to a particle's bed gradient, Hessian and still-water depth.

    ``w``: the node's weight, ``(wx, wy)``: its gradient; ``z``, ``(h0, h1, h2)``, ``still``:
    the node's elevation, Hessian ``(Z_xx, Z_xy, Z_yy)`` and still-water depth. Returns the six
    sums (the Hessian only in the slope form, ``H`` only with a still-water level). Scalars
    only: a helper that takes arrays costs a reference-count call per array and call inside
    the caller's loop (numba does not prune them), which made the force pass nine times
    slower (session 34).
    """
    gx += wx * z
    gy += wy * z
    if slope_form:
        hxx += w * h0
        hxy += w * h1
        hyy += w * h2
    if wb:
        big += w * still
    return gx, gy, hxx, hxy, hyy, big


@numba.njit(cache=True, inline="always")
def particle_force(gx, gy, hxx, hxy, hyy, big, slope_form, wb, rho, g, volume, h, u, v, sxx,
                   syy, sxy):
    """One particle's body force and force tensor (seed eqs. 26, 34; 46 with ``wb``).

    ``(gx, gy)``: the bed gradient at the particle; ``hxx, hxy, hyy``: the bed's Hessian
    (slope form); ``big``: the still-water depth ``H``; then the particle's ``V_p, h_p, u_p,
    v_p`` and stress. Returns ``(G_p, body x, body y, t_xx, t_yy, t_xy, speed)`` with the wave
    speed ``|v_p| + sqrt(max(G_p, g) h_p)`` (scalars only, see :func:`bed_terms`).
    """
    grav = g
    if slope_form:
        uhu = u * (hxx * u + hxy * v) + v * (hxy * u + hyy * v)
        cos2 = 1.0 / (1.0 + gx * gx + gy * gy)
        grav = cos2 * max(g + uhu, 0.0)
    if wb:
        area = volume / h
        weight = rho * grav * area * (h - big)  # eq. 46: -ρ g (h - H) ∇Z
        pressure = 0.5 * rho * grav * area * (h * h - big * big)
    else:
        weight = rho * grav * volume  # eq. 34: -m_p g ∇Z
        pressure = 0.5 * rho * grav * volume * h  # eq. 26: ½ ρ g h V_p
    return (grav, -weight * gx, -weight * gy, pressure - volume * sxx, pressure - volume * syy,
            -volume * sxy, math.sqrt(u * u + v * v) + math.sqrt(max(grav, g) * h))


@numba.njit(cache=True, inline="always")
def running_bound(m, x):
    """Return the running max of ``|x|``, infinity after a NaN (no NaN passes unseen)."""
    a = abs(x)
    if a != a:
        return np.inf
    return a if a > m else m


@numba.njit(cache=True)
def transfer_bounds(basis, mass, u, v, forces, area,
                    volume):
    """Per-rank maxima for :func:`mpm.exchange.p2g_bounds`, one pass.

    Returns:
        (15,) ``max |m|, |m u|, |m v|, |body x|, |body y|, |t_xx|, |t_yy|, |t_xy|``, a bound
        of ``|dN|``, ``max |A|, |V|``, then the nodes' ``-min(row), max(row), -min(column),
        max(column)`` (``-inf`` with no particle).
    """
    i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy = basis
    b = np.zeros(15)
    b[11:] = -np.inf
    t = NO_BOUNDS
    for p in range(i0.size):
        t = particle_bounds(t, mass[p], u[p], v[p], forces[0, p], forces[1, p], forces[2, p],
                            forces[3, p], forces[4, p], area[p], volume[p])
        mx, my, mdx, mdy = 0.0, 0.0, 0.0, 0.0  # a bound of |dN| from the factors' maxima
        for a in range(3):  # (a NaN position is caught by the health check)
            mx, my = max(mx, abs(wx[p, a])), max(my, abs(wy[p, a]))
            mdx, mdy = max(mdx, abs(dwx[p, a])), max(mdy, abs(dwy[p, a]))
        b[8] = max(b[8], mdx * my, mx * mdy)
        b[11], b[12] = max(b[11], -float(j0[p])), max(b[12], float(min(j0[p] + 2, ny)))
        b[13], b[14] = max(b[13], -float(i0[p])), max(b[14], float(min(i0[p] + 2, nx)))
    put_bounds(b, t)
    return b


#: The running maxima of :func:`particle_bounds` before any particle.
NO_BOUNDS = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@numba.njit(cache=True, inline="always")
def particle_bounds(t, m, u, v, f0, f1, f2, f3, f4, area, volume):
    """Raise the maxima ``t`` of ``|m|, |m u|, |m v|``, the forces, ``|A|, |V|`` to a particle's.

    ``t`` is a tuple (entries 0-7, 9 and 10 of :func:`transfer_bounds`, written by
    :func:`put_bounds`); the particle's mass, velocity, five forces, area and volume are
    scalars (see :func:`bed_terms`).
    """
    return (running_bound(t[0], m), running_bound(t[1], m * u), running_bound(t[2], m * v),
            running_bound(t[3], f0), running_bound(t[4], f1), running_bound(t[5], f2),
            running_bound(t[6], f3), running_bound(t[7], f4), running_bound(t[8], area),
            running_bound(t[9], volume))


@numba.njit(cache=True, inline="always")
def put_bounds(b, t):
    """Write :func:`particle_bounds`' maxima ``t`` into entries 0-7, 9 and 10 of ``b``."""
    for c in range(8):
        b[c] = t[c]
    b[9], b[10] = t[8], t[9]
