"""Particle domains as convex quadrilaterals cut by the mesh's cells (issue 17).

A particle's domain on a gmsh mesh is a convex quadrilateral in physical space, its corners
stored as offsets from the particle (:class:`mpm.particles.Particles`, ``q0x .. q3y``). The
domain is cut by every cell it overlaps (Sutherland–Hodgman: a convex polygon clipped by a
convex cell, or by the two triangles of a cell with a reflex corner), the pieces are fanned
into triangles and integrated with Dunavant's seven-point rule of degree 5, each point mapped
into its cell's reference coordinates. The weights of the cells' Q1 basis over the domain are
then exact wherever a cell is a parallelogram (``N_i`` is quadratic and ``∇N_i`` linear in
``x`` there), close to it on any cell (a rule of degree 2 left a 3e-4 m error in Thacker's
initial depth that did not shrink with the cells), and continuous as the domain moves (a
piece grows from zero area).

Unlike a rectangle in the reference coordinates of the particle's cell, a physical domain
does not change shape when the particle enters a differently shaped cell: the domains seeded
as the sub-cells tile the material and keep tiling it as they move and deform together, on
any cells (docs/meshes.md, "DAMPM on a gmsh mesh").
"""

from __future__ import annotations

import numba
import numpy as np

from mpm.mesh_locate import inverse_anchor, inverse_map, invert_near, map_point

__all__ = ["MAX_VISITED", "cell_polygon", "clip", "convex_parts", "cost_estimate", "crossed_sides",
           "polygon_area", "polygon_centroid", "quad_points", "seed_quads"]

#: Most cells a domain's search visits (the cells it overlaps and their neighbours).
MAX_VISITED = 48
#: Dunavant's seven-point rule of degree 5 on a triangle: barycentric coordinates, weight.
_RULE = np.array([
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.225],
    [0.059715871789770, 0.470142064105115, 0.470142064105115, 0.132394152788506],
    [0.470142064105115, 0.059715871789770, 0.470142064105115, 0.132394152788506],
    [0.470142064105115, 0.470142064105115, 0.059715871789770, 0.132394152788506],
    [0.797426985353087, 0.101286507323456, 0.101286507323456, 0.125939180544827],
    [0.101286507323456, 0.797426985353087, 0.101286507323456, 0.125939180544827],
    [0.101286507323456, 0.101286507323456, 0.797426985353087, 0.125939180544827]])


@numba.njit(cache=True, inline="always")
def cell_polygon(geo, origin, k0, m, cx, cy):
    """Write cell ``m``'s corners relative to cell ``k0``'s origin, counter-clockwise.

    Returns whether the order was reversed (corners ``(0,0), (0,1), (1,1), (1,0)`` instead of
    ``(0,0), (1,0), (1,1), (0,1)``), which :func:`crossed_sides` needs.
    """
    ox, oy = origin[m, 0] - origin[k0, 0], origin[m, 1] - origin[k0, 1]
    cx[0], cy[0] = ox, oy
    cx[1], cy[1] = ox + geo[m, 0], oy + geo[m, 1]
    cx[2], cy[2] = (ox + geo[m, 0] + geo[m, 2] + geo[m, 4],
                    oy + geo[m, 1] + geo[m, 3] + geo[m, 5])
    cx[3], cy[3] = ox + geo[m, 2], oy + geo[m, 3]
    if polygon_area(cx, cy, 4) < 0.0:
        cx[1], cx[3] = cx[3], cx[1]
        cy[1], cy[3] = cy[3], cy[1]
        return True
    return False


@numba.njit(cache=True, inline="always")
def crossed_sides(px, py, cx, cy, reversed_order, out):
    """Mark in ``out`` (4) the cell sides whose line has a vertex of ``(px, py)[:4]`` beyond it.

    Sides in :func:`mpm.mesh_locate.walk_from`'s order (``ξ = 0, ξ = 1, η = 0, η = 1``): only
    across those can the neighbours hold part of the polygon (``c`` from
    :func:`cell_polygon`, which says whether its order was reversed).
    """
    for e in range(4):
        f = e + 1 if e < 3 else 0
        ex, ey = cx[f] - cx[e], cy[f] - cy[e]
        beyond = False
        for i in range(4):
            if ex * (py[i] - cy[e]) - ey * (px[i] - cx[e]) < 0.0:
                beyond = True
        side = (2, 1, 3, 0)[e] if not reversed_order else (0, 3, 1, 2)[e]
        out[side] = beyond


@numba.njit(cache=True, inline="always")
def convex_parts(cx, cy, tx, ty, tn):
    """Split the counter-clockwise quadrilateral ``c`` into convex parts; returns their count.

    A convex cell is one part; a cell with a reflex corner ``r`` is cut along the diagonal
    from it into the triangles ``(r, r+1, r+2)`` and ``(r, r+2, r+3)``. Parts go to
    ``tx, ty`` (2, 4) with their corner counts in ``tn``.
    """
    reflex = -1
    for i in range(4):
        a, b, c = i - 1 if i > 0 else 3, i, i + 1 if i < 3 else 0
        turn = (cx[b] - cx[a]) * (cy[c] - cy[b]) - (cy[b] - cy[a]) * (cx[c] - cx[b])
        if turn < 0.0:
            reflex = i
    if reflex < 0:
        for i in range(4):
            tx[0, i], ty[0, i] = cx[i], cy[i]
        tn[0] = 4
        return 1
    for part in range(2):
        for j in range(3):
            v = (reflex + (j if part == 0 or j == 0 else j + 1)) % 4
            tx[part, j], ty[part, j] = cx[v], cy[v]
        tn[part] = 3
    return 2


@numba.njit(cache=True, inline="always")
def polygon_area(x, y, n):
    """Signed area of the polygon ``(x, y)[:n]`` (positive counter-clockwise)."""
    s = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        s += x[i] * y[j] - x[j] * y[i]
    return 0.5 * s


@numba.njit(cache=True, inline="always")
def polygon_centroid(x, y, n, area):
    """Centroid of the polygon ``(x, y)[:n]`` of signed area ``area``."""
    gx, gy = 0.0, 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        cr = x[i] * y[j] - x[j] * y[i]
        gx += (x[i] + x[j]) * cr
        gy += (y[i] + y[j]) * cr
    return gx / (6.0 * area), gy / (6.0 * area)


@numba.njit(cache=True, inline="always")
def clip(px, py, n, cx, cy, nc, ox, oy):
    """Clip the convex polygon ``(px, py)[:n]`` by the convex counter-clockwise ``c[:nc]``.

    Sutherland–Hodgman, edge by edge; the result is left in ``(px, py)`` (``(ox, oy)`` is
    scratch of the same length). Returns the result's vertex count (< 3: no overlap) and
    whether an edge cut the polygon (if not, it lies inside ``c``).
    """
    cut = False
    for e in range(nc):
        ax, ay = cx[e], cy[e]
        f = e + 1 if e < nc - 1 else 0
        ex, ey = cx[f] - ax, cy[f] - ay
        m = 0
        for i in range(n):
            j = i + 1 if i + 1 < n else 0
            ds = ex * (py[i] - ay) - ey * (px[i] - ax)
            dt = ex * (py[j] - ay) - ey * (px[j] - ax)
            if ds >= 0.0:
                ox[m], oy[m] = px[i], py[i]
                m += 1
            if (ds >= 0.0) != (dt >= 0.0):
                cut = True
                t = ds / (ds - dt)
                ox[m], oy[m] = px[i] + t * (px[j] - px[i]), py[i] + t * (py[j] - py[i])
                m += 1
        for i in range(m):
            px[i], py[i] = ox[i], oy[i]
        cut = cut or m < n
        n = m
        if n < 3:
            return n, True
    return n, cut


@numba.njit(cache=True, inline="always")
def quad_points(geo, origin, k0, m, px, py, n, qa, qb, qw, near_a, near_b):
    """Write the quadrature points of the polygon ``(px, py)[:n]`` (inside cell ``m``).

    Fans the polygon into triangles from its first vertex; seven points per triangle
    (Dunavant's rule of degree 5). Writes their
    reference coordinates in cell ``m`` to ``qa, qb`` and weights to ``qw``; returns the point
    count (``k0``: the cell the polygon's coordinates are relative to). The points are
    inverted from a known point of the cell (:func:`invert_near`): ``(near_a, near_b)`` if
    ``m == k0`` (the particle's own reference coordinates), else the cell's centre.
    """
    ox, oy = origin[m, 0] - origin[k0, 0], origin[m, 1] - origin[k0, 1]
    count = 0
    for t in range(1, n - 1):
        x0, y0, x1, y1, x2, y2 = px[0], py[0], px[t], py[t], px[t + 1], py[t + 1]
        area = 0.5 * abs((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))
        if area == 0.0:
            continue
        for g in range(_RULE.shape[0]):
            l0, l1, l2 = _RULE[g, 0], _RULE[g, 1], _RULE[g, 2]
            qa[count] = l0 * x0 + l1 * x1 + l2 * x2 - ox
            qb[count] = l0 * y0 + l1 * y1 + l2 * y2 - oy
            qw[count] = area * _RULE[g, 3]
            count += 1
    if count == 0:
        return 0
    # the branch of the inverse from the anchor holds in the whole (convex) cell: det J > 0
    a0, b0 = (near_a, near_b) if m == k0 else (0.5, 0.5)
    anchor = inverse_anchor(geo, m, a0, b0)
    x0, y0 = map_point(geo, m, a0, b0)  # the anchor's own point: r exact relative to it
    for q in range(count):
        a, b = invert_near(geo, m, anchor, qa[q] - x0, qb[q] - y0, qa[q], qb[q])
        qa[q], qb[q] = min(max(a, 0.0), 1.0), min(max(b, 0.0), 1.0)
    return count


@numba.njit(cache=True)
def seed_quads(geo, cell, xi, eta, half):
    """Return the sub-cells ``[ξ ± half] × [η ± half]`` as domains: ``(ξ_c, η_c, area, quad)``.

    The corners are the images of the reference corners; the particle moves to the
    sub-cell's centroid ``(ξ_c, η_c)``, ``area`` is the sub-cell's (exact: its edges are
    straight) and ``quad`` (n, 8) its corners' offsets from the centroid, counter-clockwise.
    """
    n = cell.size
    xo, yo, area, quad = np.empty(n), np.empty(n), np.empty(n), np.empty((n, 8))
    x, y = np.empty(4), np.empty(4)
    for p in range(n):
        k = cell[p]
        for c in range(4):
            a = xi[p] + (half if c == 1 or c == 2 else -half)
            b = eta[p] + (half if c >= 2 else -half)
            x[c] = geo[k, 0] * a + geo[k, 2] * b + geo[k, 4] * a * b
            y[c] = geo[k, 1] * a + geo[k, 3] * b + geo[k, 5] * a * b
        s = polygon_area(x, y, 4)
        if s < 0.0:
            x[1], x[3], y[1], y[3] = x[3], x[1], y[3], y[1]
            s = -s
        gx, gy = polygon_centroid(x, y, 4, s)
        xo[p], yo[p], _ = inverse_map(geo, k, gx, gy)
        area[p] = s
        for c in range(4):
            quad[p, 2 * c], quad[p, 2 * c + 1] = x[c] - gx, y[c] - gy
    return xo, yo, area, quad


@numba.njit(cache=True)
def cost_estimate(geo, origin, cell, xi, eta, quad):
    """Relative cost of each particle's step, 1, 2 or 3 (load balance only).

    A domain inside its cell costs 1, one across one side 2, one across two (a vertex) 3,
    after avaKot's corridor: the domain weights (:func:`mpm.mesh_weights.domain_basis`) took
    0.5 µs per particle inside a cell and 1.2 µs across edges, and the transfers follow the
    4, 6 or 9 entries. From the corners' sides alone (:func:`crossed_sides`).
    """
    n = cell.size
    out = np.empty(n, dtype=np.int64)
    cx, cy, sx, sy = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    cross = np.zeros(4, dtype=np.bool_)
    for p in range(n):
        k = cell[p]
        px, py = map_point(geo, k, xi[p], eta[p])
        for c in range(4):
            sx[c], sy[c] = px + quad[p, 2 * c], py + quad[p, 2 * c + 1]
        crossed_sides(sx, sy, cx, cy, cell_polygon(geo, origin, k, k, cx, cy), cross)
        out[p] = 1 + min(int(cross[0]) + int(cross[1]) + int(cross[2]) + int(cross[3]), 2)
    return out
