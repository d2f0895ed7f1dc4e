"""Quadrilateral particle domains on a gmsh mesh: deformation and splitting (issue 17).

On a gmsh mesh a particle's domain is a convex quadrilateral (:mod:`mpm.mesh_clip`) given by
its corners' offsets from the particle. The domain follows the flow's velocity gradient at
the particle, every offset ``r ← (I + Δt ∇v_p) r`` (as in CPDI; the area changes by
``det(I + Δt ∇v)``, the factor of seed eq. 42 to first order), so domains seeded as the
sub-cells keep tiling the material while the flow is smooth, whatever the cells' shapes.

Bounds as on the grid (:mod:`mpm.split`): the domain's affine part ``R = [r_s, r_t]``
(``r_s``, ``r_t``: half the vectors between opposite edges' midpoints) has singular values
``σ_1 >= σ_2``; beyond the aspect ratio :data:`mpm.split.MAX_ASPECT` the domain is mapped by
``U diag(σ'/σ) U^T`` to the same area with ``σ'_1/σ'_2`` at the bound (continuous: the map is
the identity at the bound), and a particle thinner than ``thin_depth`` keeps ``σ'`` within
the split limit. All of it in the units of the particle's cell (``J^{-1} R``, ``J`` at the
cell's centre), as the grid bounds ``l_x/Δx`` and ``l_y/Δy``. A particle whose ``r_s`` or
``r_t`` exceeds the limit ``min(1/n, 1/2)`` in those units is cut in two at the midpoints of
that direction's edges; the children move to their halves' centroids and share the volume
in proportion to their areas (the larger keeps the parent's id and ``V_a``, the other
``V - V_a``: exact).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mpm.mesh_clip import polygon_area, polygon_centroid
from mpm.particles import Particles
from mpm.split import DomainSplitter

__all__ = ["RESPLIT", "QuadSplitter"]

#: A domain still wider than this many split limits after a step's pair of cuts is cut again
#: at once (collective); one between 1 and this many limits is cut in the next step's pair.
#: On the grid a pair leaves a domain too wide only if it was more than twice the limit; on a
#: mesh a half that moves into a smaller cell can come out a few percent over the limit in
#: that cell's units (on the hemisphere's gmsh disc after half the steps), which cutting at once
#: would cost a second evaluation of every particle's weights.
RESPLIT = 2.0


@numba.njit(cache=True, inline="always")
def _half_vectors(q, p):
    """``r_s, r_t`` of particle ``p``'s corner offsets ``q`` (the eight arrays)."""
    sx = 0.25 * ((q[2][p] + q[4][p]) - (q[0][p] + q[6][p]))
    sy = 0.25 * ((q[3][p] + q[5][p]) - (q[1][p] + q[7][p]))
    tx = 0.25 * ((q[4][p] + q[6][p]) - (q[0][p] + q[2][p]))
    ty = 0.25 * ((q[5][p] + q[7][p]) - (q[1][p] + q[3][p]))
    return sx, sy, tx, ty


@numba.njit(cache=True)
def _deform(q, grad, dt, h, thin_depth, cell, jac, limit, max_aspect):
    """Map the offsets by ``I + Δt ∇v``, then bound the aspect ratio and thin domains.

    ``q``: the eight corner-offset arrays (:meth:`mpm.particles.Particles.quad_columns`),
    changed in place. The bounds act in the units of the particle's cell (``jac``:
    (n_cells, 4) its Jacobian ``(x_ξ, x_η, y_ξ, y_η)`` at the centre), as the grid's do in
    ``Δx, Δy``.
    """
    for p in range(q[0].size):
        a00, a01 = 1.0 + dt * grad[p, 0, 0], dt * grad[p, 0, 1]
        a10, a11 = dt * grad[p, 1, 0], 1.0 + dt * grad[p, 1, 1]
        for c in range(4):
            x, y = q[2 * c][p], q[2 * c + 1][p]
            q[2 * c][p], q[2 * c + 1][p] = a00 * x + a01 * y, a10 * x + a11 * y
        j00, j01, j10, j11 = jac[cell[p], 0], jac[cell[p], 1], jac[cell[p], 2], jac[cell[p], 3]
        det = j00 * j11 - j01 * j10
        i00, i01, i10, i11 = j11 / det, -j01 / det, -j10 / det, j00 / det
        sx, sy, tx, ty = _half_vectors(q, p)
        sx, sy = i00 * sx + i01 * sy, i10 * sx + i11 * sy  # in cell units
        tx, ty = i00 * tx + i01 * ty, i10 * tx + i11 * ty
        m00, m01, m11 = sx * sx + tx * tx, sx * sy + tx * ty, sy * sy + ty * ty  # R R^T
        mean, dev = 0.5 * (m00 + m11), math.sqrt(0.25 * (m00 - m11) ** 2 + m01 * m01)
        s1, s2 = math.sqrt(mean + dev), math.sqrt(max(mean - dev, 0.0))
        if s1 == 0.0:
            continue  # a point particle stays one
        n1, n2 = s1, s2
        if s1 > max_aspect * s2:
            n1, n2 = math.sqrt(s1 * s2 * max_aspect), math.sqrt(s1 * s2 / max_aspect)
        if h[p] < thin_depth:
            n1, n2 = min(n1, limit), min(n2, limit)
        if n1 == s1 and n2 == s2:
            continue
        th = 0.5 * math.atan2(2.0 * m01, m00 - m11)
        ux, uy = math.cos(th), math.sin(th)  # the direction of σ_1 (cell units)
        f1, f2 = n1 / s1, (n2 / s2 if s2 > 0.0 else 1.0)
        r00, r01 = f1 * ux * ux + f2 * uy * uy, (f1 - f2) * ux * uy
        r11 = f1 * uy * uy + f2 * ux * ux
        # T = J T_ref J^{-1}
        b00, b01 = r00 * i00 + r01 * i10, r00 * i01 + r01 * i11
        b10, b11 = r01 * i00 + r11 * i10, r01 * i01 + r11 * i11
        t00, t01 = j00 * b00 + j01 * b10, j00 * b01 + j01 * b11
        t10, t11 = j10 * b00 + j11 * b10, j10 * b01 + j11 * b11
        for c in range(4):
            x, y = q[2 * c][p], q[2 * c + 1][p]
            q[2 * c][p], q[2 * c + 1][p] = t00 * x + t01 * y, t10 * x + t11 * y


@numba.njit(cache=True)
def _widths(q, cell, jac):
    """(n, 2) ``|r_s|, |r_t|`` of every domain in its cell's units (``q``: the eight arrays)."""
    out = np.empty((q[0].size, 2))
    for p in range(q[0].size):
        j00, j01, j10, j11 = jac[cell[p], 0], jac[cell[p], 1], jac[cell[p], 2], jac[cell[p], 3]
        det = j00 * j11 - j01 * j10
        sx, sy, tx, ty = _half_vectors(q, p)
        ax, ay = (j11 * sx - j01 * sy) / det, (-j10 * sx + j00 * sy) / det
        bx, by = (j11 * tx - j01 * ty) / det, (-j10 * tx + j00 * ty) / det
        out[p, 0], out[p, 1] = math.sqrt(ax * ax + ay * ay), math.sqrt(bx * bx + by * by)
    return out


@numba.njit(cache=True)
def _cut(q, axis):
    """Halves of the domains ``q`` (n, 8) along ``axis``: ``(keep, other, cen_k, cen_o, frac)``.

    Corners and centroids relative to the parent particle; ``keep`` is the larger half and
    ``frac`` its share of the area.
    """
    n = q.shape[0]
    keep, other = np.empty((n, 8)), np.empty((n, 8))
    cen = np.empty((2, n, 2))
    frac = np.empty(n)
    x, y, c = np.empty(4), np.empty(4), np.empty(8)
    for p in range(n):
        for k in range(8):
            c[k] = q[p, k]
        # the midpoints of the two edges across the axis; halves in corner order 0..3
        i0, i1, i2, i3 = (0, 1, 2, 3) if axis == 0 else (1, 2, 3, 0)
        ax, ay = 0.5 * (c[2 * i0] + c[2 * i1]), 0.5 * (c[2 * i0 + 1] + c[2 * i1 + 1])
        bx, by = 0.5 * (c[2 * i3] + c[2 * i2]), 0.5 * (c[2 * i3 + 1] + c[2 * i2 + 1])
        halves = ((c[2 * i0], c[2 * i0 + 1], ax, ay, bx, by, c[2 * i3], c[2 * i3 + 1]),
                  (ax, ay, c[2 * i1], c[2 * i1 + 1], c[2 * i2], c[2 * i2 + 1], bx, by))
        areas = np.empty(2)
        for s in range(2):
            for k in range(4):
                x[k], y[k] = halves[s][2 * k], halves[s][2 * k + 1]
            areas[s] = polygon_area(x, y, 4)
            gx, gy = polygon_centroid(x, y, 4, areas[s])
            cen[s, p, 0], cen[s, p, 1] = gx, gy
            dst = keep if s == 0 else other
            for k in range(4):  # back to the corner order of the parent
                slot = (i0, i1, i2, i3)[k]
                dst[p, 2 * slot], dst[p, 2 * slot + 1] = x[k], y[k]
        big = 0 if areas[0] >= areas[1] else 1
        if big == 1:
            for k in range(8):
                keep[p, k], other[p, k] = other[p, k], keep[p, k]
            for d in range(2):
                cen[0, p, d], cen[1, p, d] = cen[1, p, d], cen[0, p, d]
        frac[p] = areas[big] / (areas[0] + areas[1])
    return keep, other, cen[0], cen[1], frac


class QuadSplitter(DomainSplitter):
    """:class:`mpm.split.DomainSplitter` for quadrilateral domains (see the module docstring).

    Args:
        grid: The mesh's particle grid (:class:`mpm.mesh_grid.MeshParticleGrid`).
        per_direction: Particles per cell and direction at the start.
        next_id: First unused particle id (the same on every rank).
        thin_depth: Particles thinner than this [m] are not split (their domain is capped).
    """

    def __init__(self, grid, per_direction: int, next_id: int, thin_depth: float = 0.0) -> None:
        super().__init__(grid, per_direction, next_id, thin_depth)
        self._limit = min(1.0 / self.per_direction, 0.5)
        self._jac = grid.centre_jacobians()

    def stretch(self, p: Particles, dt: float, grad: np.ndarray) -> None:
        """Deform the domains with ``I + Δt ∇v_p`` and bound them (in place)."""
        _deform(p.quad_columns(), grad, dt, p.h, self.thin_depth, p.cell, self._jac,
                self._limit, self.max_aspect)

    def widths(self, p: Particles) -> np.ndarray:
        """(n, 2) half-extents ``|J^{-1} r_s|, |J^{-1} r_t|`` of the domains (cell units)."""
        return _widths(p.quad_columns(), p.cell, self._jac)

    def _any_wide_here(self, parts: list[Particles]) -> bool:
        """Whether a domain on this rank exceeds :data:`RESPLIT` limits (local)."""
        return any(bool((self.widths(p) > RESPLIT * self._limit).any()) for p in parts)

    def _wide(self, p: Particles, axis: int) -> np.ndarray:
        """Return the indices of the domains too long in direction ``axis`` (0: s, 1: t)."""
        return np.flatnonzero(self.widths(p)[:, axis] > self._limit)

    def _halve(self, p: Particles, idx: np.ndarray, axis: int) -> Particles:
        """Cut domains ``idx`` of ``p`` in two along ``axis`` in place; return the others."""
        keep, other, cen_k, cen_o, frac = _cut(p.quad_at(idx), axis)
        volume = p.volume[idx]
        kept = volume * frac
        p.volume[idx] = kept
        child = p.select(idx)
        child.volume = volume - kept
        self._place(p, idx, keep, cen_k)
        self._place(child, np.arange(len(child)), other, cen_o)
        return child

    def _place(self, p: Particles, idx: np.ndarray, quad: np.ndarray, cen: np.ndarray) -> None:
        """Move particles ``idx`` by ``cen`` (inside the mesh); set their corners (in place)."""
        x0, y0 = self.grid.positions(p.cell[idx], p.xi[idx], p.eta[idx])
        cell, xi, eta, _, _ = self.grid.displace(p.cell[idx], p.xi[idx], p.eta[idx],
                                                 cen[:, 0], cen[:, 1])
        p.cell[idx], p.xi[idx], p.eta[idx] = cell, xi, eta
        x1, y1 = self.grid.positions(cell, xi, eta)
        dx, dy = x1 - x0, y1 - y0  # the walk stops at the mesh's boundary
        quad = quad.copy()
        quad[:, 0::2] -= dx[:, None]
        quad[:, 1::2] -= dy[:, None]
        p.set_quad_at(idx, quad)
        if p.has_affine:  # APIC: each half moves with the affine velocity at its centre
            p.u[idx] += p.cxx[idx] * dx + p.cxy[idx] * dy
            p.v[idx] += p.cyx[idx] * dx + p.cyy[idx] * dy

