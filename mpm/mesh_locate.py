"""Numba kernels of DAMPM on a quadrilateral mesh: locating points, cell geometry.

Every cell ``k`` is ``x(ξ, η) = x_0 + e_1 ξ + e_2 η + c ξ η`` (``geo[k] = e_1, e_2, c``,
``origin[k] = x_0``; corners in basix order ``(0,0), (1,0), (0,1), (1,1)``). Points are kept
as a cell and reference coordinates (:mod:`mpm.mesh_grid`); their weights are in
:mod:`mpm.mesh_weights`.
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.compiled import without_refcounts

__all__ = ["INSIDE", "MAX_WALK", "NEWTON", "NEWTON_STEP", "WALK_EDGES", "inverse_anchor",
           "inverse_map", "invert_near", "jacobian_det", "map_point", "newton", "tangents", "walk",
           "walk_from"]

#: Corners of the four edges in the walk's order: ξ = 0, ξ = 1, η = 0, η = 1.
WALK_EDGES = np.array([[0, 2], [1, 3], [0, 1], [2, 3]], dtype=np.int64)
#: A point within this much (reference units) of a cell counts as inside it.
INSIDE = 1e-12
#: Most cells a walk visits in one displacement.
MAX_WALK = 64
#: Most Newton iterations of the inverse bilinear map.
NEWTON = 20
#: Newton stops after a step this small: it converges quadratically, so what remains is of
#: the order of its square (1e-18 of a cell).
NEWTON_STEP = 1e-9


@numba.njit(cache=True, inline="always")
def map_point(geo, k, a, b):
    """``x(ξ, η) - x_0`` of cell ``k`` (geo[k] = e1, e2, c as 6 numbers)."""
    return (geo[k, 0] * a + geo[k, 2] * b + geo[k, 4] * a * b,
            geo[k, 1] * a + geo[k, 3] * b + geo[k, 5] * a * b)


@numba.njit(cache=True, inline="always")
def newton(geo, k, rx, ry, a, b):
    """Newton for ``x(ξ, η) - x(a, b) = r`` in cell ``k`` from ``(a, b)``: ``(ξ, η, converged)``.

    The residual is formed from differences (``e_1 dξ + e_2 dη + c (ξ η - a b)``), so a zero
    displacement returns ``(a, b)`` exactly and far-away coordinates lose no digits.
    """
    da, db = 0.0, 0.0
    for _ in range(NEWTON):
        na, nb = a + da, b + db
        fx = geo[k, 0] * da + geo[k, 2] * db + geo[k, 4] * (na * nb - a * b) - rx
        fy = geo[k, 1] * da + geo[k, 3] * db + geo[k, 5] * (na * nb - a * b) - ry
        j00, j01 = geo[k, 0] + geo[k, 4] * nb, geo[k, 2] + geo[k, 4] * na
        j10, j11 = geo[k, 1] + geo[k, 5] * nb, geo[k, 3] + geo[k, 5] * na
        det = j00 * j11 - j01 * j10
        if det == 0.0:
            break
        inv = 1.0 / det  # one division per iteration: 11 % of the domain weights' cost
        sa = (j11 * fx - j01 * fy) * inv
        sb = (j00 * fy - j10 * fx) * inv
        da -= sa
        db -= sb
        if abs(sa) + abs(sb) <= NEWTON_STEP:
            return a + da, b + db, True
    return a + da, b + db, False


@numba.njit(cache=True, inline="always")
def inverse_map(geo, k, tx, ty):
    """Find the reference coordinates of the point ``t`` (relative to cell ``k``'s origin).

    Newton from the affine estimate at the centre: ``(ξ, η, converged)`` (the estimate if not).
    """
    mx, my = map_point(geo, k, 0.5, 0.5)
    j00, j10, j01, j11 = geo[k, 0] + 0.5 * geo[k, 4], geo[k, 1] + 0.5 * geo[k, 5], \
        geo[k, 2] + 0.5 * geo[k, 4], geo[k, 3] + 0.5 * geo[k, 5]
    det = j00 * j11 - j01 * j10
    rx, ry = tx - mx, ty - my
    a = min(max(0.5 + (j11 * rx - j01 * ry) / det, -2.0), 3.0)
    b = min(max(0.5 + (-j10 * rx + j00 * ry) / det, -2.0), 3.0)
    if -0.5 <= a <= 1.5 and -0.5 <= b <= 1.5:  # near the cell: the bilinear map is one-to-one
        ex, ey = map_point(geo, k, a, b)
        na, nb, ok = newton(geo, k, tx - ex, ty - ey, a, b)
        if ok:
            return na, nb, True
    return a, b, False


@numba.njit(cache=True, inline="always")
def inverse_anchor(geo, m, a0, b0):
    """Return ``(a0, b0, J0⁻¹ (4), J0⁻¹ c (2))`` of cell ``m`` at ``(a0, b0)``.

    The data :func:`invert_near` inverts the map near ``(a0, b0)`` with.
    """
    j00, j10, j01, j11 = tangents(geo, m, a0, b0)
    inv = 1.0 / (j00 * j11 - j01 * j10)
    i00, i01, i10, i11 = j11 * inv, -j01 * inv, -j10 * inv, j00 * inv
    return (a0, b0, i00, i01, i10, i11, i00 * geo[m, 4] + i01 * geo[m, 5],
            i10 * geo[m, 4] + i11 * geo[m, 5])


@numba.njit(cache=True, inline="always")
def invert_near(geo, m, anchor, rx, ry, tx, ty):
    """Return the reference coordinates of the point ``x(a0, b0) + r`` of cell ``m``.

    The bilinear map gives ``x(a0 + dξ, b0 + dη) - x(a0, b0) = J0 d + c dξ dη``, so with
    ``e = J0⁻¹ r`` and ``k = J0⁻¹ c``: ``d = e - k P``, ``P = dξ dη`` the small root of
    ``k_ξ k_η P² - (1 + e_ξ k_η + e_η k_ξ) P + e_ξ e_η = 0`` (in the form without
    cancellation). Newton from the anchor, and from the cell's centre (``t``: the point
    relative to the cell's origin), where that root does not exist.
    """
    a0, b0, i00, i01, i10, i11, kx, ky = anchor
    ea, eb = i00 * rx + i01 * ry, i10 * rx + i11 * ry
    half_b = 0.5 * (1.0 + ea * ky + eb * kx)
    disc = half_b * half_b - kx * ky * (ea * eb)
    if half_b > 0.0 and disc >= 0.0:
        pr = (ea * eb) / (half_b + np.sqrt(disc))
        return a0 + (ea - kx * pr), b0 + (eb - ky * pr)
    a, b, ok = newton(geo, m, rx, ry, a0, b0)
    if not ok:
        a, b, _ = inverse_map(geo, m, tx, ty)
    return a, b


@numba.njit(cache=True, inline="always")
def _locate(geo, origin, neighbour, kind, k, a0, b0, dx, dy):
    """Locate the point ``x(a0, b0) + (dx, dy)`` of cell ``k``: ``(cell, ξ, η, code)``.

    The point is first inverted in ``k`` in closed form from ``(a0, b0)`` (:func:`invert_near`;
    a zero move keeps its bits), then :func:`walk_from` walks across the edge it lies beyond
    until it is inside a cell; ``code`` is 0, or the kind of the boundary edge it stopped at
    (1 open, 2 wall), where ``(ξ, η)`` is clamped.
    """
    if dx == 0.0 and dy == 0.0:
        return k, a0, b0, 0
    px, py = map_point(geo, k, a0, b0)
    a, b = invert_near(geo, k, inverse_anchor(geo, k, a0, b0), dx, dy, px + dx, py + dy)
    return walk_from(geo, origin, neighbour, kind, k, a, b, True, px + dx, py + dy)


@numba.njit(cache=True, inline="always")
def walk_from(geo, origin, neighbour, kind, k, a, b, ok, tx, ty):
    """Locate the point ``t`` (relative to cell ``k``'s origin): ``(cell, ξ, η, code)``.

    ``(a, b)`` are its coordinates in ``k`` if ``ok``; the result is as :func:`_locate`'s.

    In each further cell its coordinates come from Newton (:func:`inverse_map`); outside, the
    walk crosses the edge it lies farthest beyond that has a cell behind it, and stops at the
    boundary only when every edge the point lies beyond is a boundary edge.
    """
    code = 0
    for _ in range(MAX_WALK):
        if not ok:
            a, b, ok = inverse_map(geo, k, tx, ty)
        e, best, wall, wall_v = -1, INSIDE, -1, INSIDE
        for s in range(4):
            v = -a if s == 0 else (a - 1.0 if s == 1 else (-b if s == 2 else b - 1.0))
            if neighbour[k, s] >= 0:
                if v > best:
                    e, best = s, v
            elif v > wall_v:
                wall, wall_v = s, v
        if e < 0:
            if wall >= 0:
                code = kind[k, wall]
            break
        nb = neighbour[k, e]
        tx += origin[k, 0] - origin[nb, 0]
        ty += origin[k, 1] - origin[nb, 1]
        k, ok = nb, False
    return k, min(max(a, 0.0), 1.0), min(max(b, 0.0), 1.0), code


@numba.njit(cache=True, inline="always")
def tangents(geo, k, a, b):
    """``∂x/∂ξ`` and ``∂x/∂η`` of cell ``k`` at ``(a, b)``: ``(x_ξ, y_ξ, x_η, y_η)``."""
    return (geo[k, 0] + geo[k, 4] * b, geo[k, 1] + geo[k, 5] * b,
            geo[k, 2] + geo[k, 4] * a, geo[k, 3] + geo[k, 5] * a)


def walk(geo, origin, neighbour, kind, cell, xi, eta, dx, dy):
    """Move points by ``(dx, dy)``: ``(cell, ξ, η, out)``; ``out``: left through an open edge."""
    c_out, a_out, b_out = cell.copy(), xi.copy(), eta.copy()
    out = np.zeros(cell.size, dtype=np.bool_)
    _walk_loop(geo, origin, neighbour, kind, cell, xi, eta, dx, dy, c_out, a_out, b_out, out)
    return c_out, a_out, b_out, out


def _walk_loop(geo, origin, neighbour, kind, cell, xi, eta, dx, dy, c_out, a_out, b_out, out):
    """:func:`walk`'s loop over the points, into given arrays (it allocates nothing)."""
    for p in range(cell.size):
        k, a, b, code = _locate(geo, origin, neighbour, kind, cell[p], xi[p], eta[p],
                                dx[p], dy[p])
        c_out[p], a_out[p], b_out[p], out[p] = k, a, b, code == 1


_walk_loop = without_refcounts(_walk_loop)


@numba.njit(cache=True)
def jacobian_det(geo, cell, xi, eta):
    """``|det J|`` at the points."""
    out = np.empty(cell.size)
    for p in range(cell.size):
        j00, j10, j01, j11 = tangents(geo, cell[p], xi[p], eta[p])
        out[p] = abs(j00 * j11 - j01 * j10)
    return out
