"""GIMP weights of DAMPM's particle domains on a quadrilateral mesh (issue 17).

A particle's domain is a rectangle in its cell's reference coordinates, cut at the cell's
edges; each piece is integrated with the 2 × 2 Gauss rule of the cell's (extended) map and
its points located in their own cells (:mod:`mpm.mesh_locate`). See :func:`domain_basis`
and docs/meshes.md, "DAMPM on a gmsh mesh".
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mpm.mesh_locate import INSIDE, map_point, newton, tangents, walk_from

__all__ = ["MAX_CELLS", "domain_basis", "point_basis"]

#: Most cells a particle domain reaches (4 around a regular vertex; up to 6 at a vertex
#: with 5 or 6 cells).
MAX_CELLS = 8


@numba.njit(cache=True, inline="always")
def _add(geo, corners, k, a, b, w, px, py, ox, oy, nodes, N, dN, rel, p, q0):
    """Add ``w N_c`` and ``w ∇N_c`` of the point ``(a, b)`` of cell ``k`` to slots ``q0..q0+3``.

    ``x_c - x_p`` is set (``(ox, oy)``: the cell's origin relative to the particle cell's).
    Written out per corner (a loop over tuples cost 10 times more).
    """
    j00, j10, j01, j11 = tangents(geo, k, a, b)
    s = w / (j00 * j11 - j01 * j10)
    # ∇N = J^{-T} ∇_ξ N: (j11 dξ - j10 dη, -j01 dξ + j00 dη) / det
    da0, db0 = -(1.0 - b), -(1.0 - a)
    da1, db1 = 1.0 - b, -a
    da2, db2 = -b, 1.0 - a
    da3, db3 = b, a
    nodes[p, q0], nodes[p, q0 + 1] = corners[k, 0], corners[k, 1]
    nodes[p, q0 + 2], nodes[p, q0 + 3] = corners[k, 2], corners[k, 3]
    N[p, q0] += w * ((1.0 - a) * (1.0 - b))
    N[p, q0 + 1] += w * (a * (1.0 - b))
    N[p, q0 + 2] += w * ((1.0 - a) * b)
    N[p, q0 + 3] += w * (a * b)
    dN[p, q0, 0] += s * (j11 * da0 - j10 * db0)
    dN[p, q0, 1] += s * (-j01 * da0 + j00 * db0)
    dN[p, q0 + 1, 0] += s * (j11 * da1 - j10 * db1)
    dN[p, q0 + 1, 1] += s * (-j01 * da1 + j00 * db1)
    dN[p, q0 + 2, 0] += s * (j11 * da2 - j10 * db2)
    dN[p, q0 + 2, 1] += s * (-j01 * da2 + j00 * db2)
    dN[p, q0 + 3, 0] += s * (j11 * da3 - j10 * db3)
    dN[p, q0 + 3, 1] += s * (-j01 * da3 + j00 * db3)
    # corner c relative to the cell origin: 0, e1, e2, e1 + e2 + c
    bx, by = ox - px, oy - py
    rel[p, q0, 0], rel[p, q0, 1] = bx, by
    rel[p, q0 + 1, 0], rel[p, q0 + 1, 1] = geo[k, 0] + bx, geo[k, 1] + by
    rel[p, q0 + 2, 0], rel[p, q0 + 2, 1] = geo[k, 2] + bx, geo[k, 3] + by
    rel[p, q0 + 3, 0] = (geo[k, 0] + geo[k, 2] + geo[k, 4]) + bx
    rel[p, q0 + 3, 1] = (geo[k, 1] + geo[k, 3] + geo[k, 5]) + by


@numba.njit(cache=True, inline="always")
def _breaks(lo, hi, out):
    """``lo``, the cell edges 0 and 1 strictly inside ``(lo, hi)``, ``hi``; returns the count."""
    out[0] = lo
    m = 1
    for edge in (0.0, 1.0):
        if lo < edge < hi:
            out[m] = edge
            m += 1
    out[m] = hi
    return m + 1


@numba.njit(cache=True, inline="always")
def _particle_domain(geo, origin, corners, neighbour, kind, k, x0, y0, lx, ly, px, py,
                     nodes, N, dN, rel, seen, bx, by, mom):
    """Fill the scratch rows ``0 .. 4 n - 1`` of one particle; returns ``n`` (cells reached)."""
    if lx == 0.0 and ly == 0.0:
        _add(geo, corners, k, x0, y0, 1.0, px, py, 0.0, 0.0, nodes, N, dN, rel, 0, 0)
        return 1
    r = 0.5 / math.sqrt(3.0)
    t00, t10, t01, t11 = tangents(geo, k, x0, y0)
    a = lx / math.sqrt(t00 * t00 + t10 * t10)
    b = ly / math.sqrt(t01 * t01 + t11 * t11)
    nbx, nby = _breaks(x0 - a, x0 + a, bx), _breaks(y0 - b, y0 + b, by)
    n_seen, total = 0, 0.0
    for ix in range(nbx - 1):
        for iy in range(nby - 1):
            du, dv = bx[ix + 1] - bx[ix], by[iy + 1] - by[iy]
            last, la, lb = -1, 0.5, 0.5
            for g in range(4):
                s = 0.5 * (bx[ix] + bx[ix + 1]) + (2.0 * (g % 2) - 1.0) * r * du
                t = 0.5 * (by[iy] + by[iy + 1]) + (2.0 * (g // 2) - 1.0) * r * dv
                j00, j10, j01, j11 = tangents(geo, k, s, t)
                w = 0.25 * du * dv * abs(j00 * j11 - j01 * j10)
                m, sa, sb = k, s, t
                if not (0.0 <= s <= 1.0 and 0.0 <= t <= 1.0):
                    m, sa, sb, code = _outside_point(geo, origin, neighbour, kind, k, s, t,
                                                     last, la, lb)
                    if code != 0:
                        continue  # beyond the mesh: the domain is clipped there
                    last, la, lb = m, sa, sb
                slot = 0
                while slot < n_seen and seen[slot] != m:
                    slot += 1
                if slot == n_seen:
                    if n_seen == MAX_CELLS:
                        continue
                    seen[slot] = m
                    n_seen += 1
                    for c in range(8):
                        mom[slot, c] = 0.0
                _moments(geo, m, sa, sb, w, mom, slot)
                total += w
    for slot in range(n_seen):
        m = seen[slot]
        _from_moments(geo, corners, m, mom, slot, 1.0 / total, px,
                      py, origin[m, 0] - origin[k, 0], origin[m, 1] - origin[k, 1], nodes, N,
                      dN, rel)
    return n_seen


@numba.njit(cache=True, inline="always")
def _outside_point(geo, origin, neighbour, kind, k, s, t, last, la, lb):
    """Locate the point ``(s, t)`` of cell ``k``'s extended map: ``(cell, ξ, η, code)``.

    First by Newton in ``last`` (the cell of the piece's previous point, at ``(la, lb)``),
    else by a walk from ``k`` (:func:`mpm.mesh_locate.walk_from`).
    """
    mx, my = map_point(geo, k, s, t)
    if last >= 0:
        rx = mx + (origin[k, 0] - origin[last, 0])
        ry = my + (origin[k, 1] - origin[last, 1])
        lx0, ly0 = map_point(geo, last, la, lb)
        sa, sb, ok = newton(geo, last, rx - lx0, ry - ly0, la, lb)
        if ok and -INSIDE <= sa <= 1.0 + INSIDE and -INSIDE <= sb <= 1.0 + INSIDE:
            return last, min(max(sa, 0.0), 1.0), min(max(sb, 0.0), 1.0), 0
    return walk_from(geo, origin, neighbour, kind, k, s, t, True, mx, my)


@numba.njit(cache=True, inline="always")
def _moments(geo, m, a, b, w, mom, slot):
    """Add a Gauss point ``(a, b)`` of cell ``m`` with weight ``w`` to the slot's moments.

    ``Σ w, Σ w a, Σ w b, Σ w a b`` and the same with ``w / det J``: the domain's ``Σ w N_c``
    and ``Σ w ∇N_c`` are linear in them (:func:`_from_moments`), so a point costs eight
    sums instead of twelve weights.
    """
    j00, j10, j01, j11 = tangents(geo, m, a, b)
    o = w / (j00 * j11 - j01 * j10)
    mom[slot, 0] += w
    mom[slot, 1] += w * a
    mom[slot, 2] += w * b
    mom[slot, 3] += w * (a * b)
    mom[slot, 4] += o
    mom[slot, 5] += o * a
    mom[slot, 6] += o * b
    mom[slot, 7] += o * (a * b)


@numba.njit(cache=True, inline="always")
def _from_moments(geo, corners, m, mom, slot, scale, px, py, ox, oy, nodes, N, dN, rel):
    """Write slot ``slot``'s four entries (cell ``m``) from its moments, times ``scale``.

    ``N_c = Σ w N_c(a, b)`` with ``N_0 = (1-a)(1-b)``, …; ``∇N_c = J^{-T} ∇_ξ N_c`` with
    ``∂_ξ N_c = α_c + β_c b``, ``∂_η N_c = γ_c + δ_c a`` and ``J`` linear in ``a, b``, so
    ``Σ (w/det) adj(J) ∇_ξ N_c`` needs only ``Σ o, Σ o a, Σ o b, Σ o a b`` (``o = w/det``).
    """
    s0, sa, sb, sab = mom[slot, 0], mom[slot, 1], mom[slot, 2], mom[slot, 3]
    w0, wa, wb, wab = mom[slot, 4], mom[slot, 5], mom[slot, 6], mom[slot, 7]
    g0, g1, g2, g3, g4, g5 = geo[m, 0], geo[m, 1], geo[m, 2], geo[m, 3], geo[m, 4], geo[m, 5]
    q0 = 4 * slot
    N[0, q0] = scale * (s0 - sa - sb + sab)
    N[0, q0 + 1] = scale * (sa - sab)
    N[0, q0 + 2] = scale * (sb - sab)
    N[0, q0 + 3] = scale * sab
    for c in range(4):
        al = -1.0 if c == 0 else (1.0 if c == 1 else 0.0)
        be = 1.0 if (c == 0 or c == 3) else -1.0
        ga = -1.0 if c == 0 else (1.0 if c == 2 else 0.0)
        de = 1.0 if (c == 0 or c == 3) else -1.0
        dN[0, q0 + c, 0] = scale * ((g3 * al - g1 * ga) * w0 + (g5 * al - g1 * de) * wa
                                    + (g3 * be - g5 * ga) * wb + (g5 * be - g5 * de) * wab)
        dN[0, q0 + c, 1] = scale * ((g0 * ga - g2 * al) * w0 + (g0 * de - g4 * al) * wa
                                    + (g4 * ga - g2 * be) * wb + (g4 * de - g4 * be) * wab)
        nodes[0, q0 + c] = corners[m, c]
    bx, by = ox - px, oy - py
    rel[0, q0, 0], rel[0, q0, 1] = bx, by
    rel[0, q0 + 1, 0], rel[0, q0 + 1, 1] = g0 + bx, g1 + by
    rel[0, q0 + 2, 0], rel[0, q0 + 2, 1] = g2 + bx, g3 + by
    rel[0, q0 + 3, 0] = (g0 + g2 + g4) + bx
    rel[0, q0 + 3, 1] = (g1 + g3 + g5) + by


@numba.njit(cache=True)
def domain_basis(geo, origin, corners, neighbour, kind, cell, xi, eta, lx, ly, offsets, nodes,
                 S, dS, rel):
    """Weights of the particle domains: GIMP on a quadrilateral mesh.

    A particle's domain is the rectangle ``[ξ_p ± a] × [η_p ± b]`` of its cell's reference
    coordinates, ``a = l_x / |∂x/∂ξ|``, ``b = l_y / |∂x/∂η|`` (``l_x, l_y``: half-widths along
    the cell's axes [m]). It is cut at the cell's edges; each piece gets the 2 × 2 Gauss rule
    in the cell's (extended) map, weights ``|det J|``, its points located in their own cells
    (points beyond the mesh boundary are dropped), and

        S_ip = Σ_q w_q N_i(x_q) / Σ_q w_q,    ∇S_ip = Σ_q w_q ∇N_i(x_q) / Σ_q w_q:

    the domain averages of GIMP, exact for a domain inside its cell (the integrands are
    polynomials of degree <= 3 per reference direction), continuous as a domain crosses an
    edge (a new piece starts with zero width), ``Σ_i S_ip = 1`` and ``Σ_i ∇S_ip = 0``.
    Domains that tile the cells (the uniform seeding) balance the pressure of a uniform layer
    exactly, as on the grid. A point particle (``l = 0``) gets the point values of seed
    eq. 33.

    The results go to ``offsets`` (n + 1) and the buffers ``nodes, S, dS, rel`` (kept by the
    caller: fresh arrays cost more in page faults than the computation): particle ``p``'s
    entries are ``offsets[p] .. offsets[p + 1] - 1``, one per node its domain reaches (the
    corners of at most :data:`MAX_CELLS` cells).

    Returns:
        The number of entries used, or -1 if the buffers are too short (call again with
        longer ones).
    """
    n = cell.size
    cap = nodes.size
    offsets[0] = 0
    w = 4 * MAX_CELLS
    snodes = np.empty((1, w), dtype=np.int64)
    sN, sdN, srel = np.zeros((1, w)), np.zeros((1, w, 2)), np.zeros((1, w, 2))
    seen = np.empty(MAX_CELLS, dtype=np.int64)
    mom = np.empty((MAX_CELLS, 8))
    bx, by = np.empty(4), np.empty(4)
    for p in range(n):
        k = cell[p]
        px, py = map_point(geo, k, xi[p], eta[p])
        for q in range(4):
            sN[0, q], sdN[0, q, 0], sdN[0, q, 1] = 0.0, 0.0, 0.0
        used = 4 * _particle_domain(geo, origin, corners, neighbour, kind, k, xi[p], eta[p],
                                    lx[p], ly[p], px, py, snodes, sN, sdN, srel, seen, bx, by,
                                    mom)
        start = offsets[p]
        if start + used > cap:
            return -1
        offsets[p + 1] = start + _append_unique(start, used, snodes, sN, sdN, srel, nodes, S,
                                                dS, rel)
    return offsets[n]


@numba.njit(cache=True, inline="always")
def _append_unique(start, used, snodes, sN, sdN, srel, nodes, S, dS, rel):
    """Copy the scratch entries to ``start`` on, one per node; returns their count.

    A node reached from several cells gets one entry with its weights added (9 entries for a
    domain around a vertex).
    """
    count = 0
    for q in range(used):
        e = start
        while e < start + count and nodes[e] != snodes[0, q]:
            e += 1
        if e == start + count:
            nodes[e], S[e] = snodes[0, q], sN[0, q]
            dS[e, 0], dS[e, 1] = sdN[0, q, 0], sdN[0, q, 1]
            rel[e, 0], rel[e, 1] = srel[0, q, 0], srel[0, q, 1]
            count += 1
        else:
            S[e] += sN[0, q]
            dS[e, 0] += sdN[0, q, 0]
            dS[e, 1] += sdN[0, q, 1]
    return count


@numba.njit(cache=True)
def point_basis(geo, corners, cell, xi, eta):
    """Q1 values ``(n, 4)`` and physical gradients ``(n, 4, 2)`` at points (local dofs: seeding).

    Args:
        geo: (n_cells, 6) ``e_1, e_2, c`` of every cell.
        corners: (n_cells, 4) nodes of the cells.
        cell: (n,) the points' cells.
        xi: (n,) first reference coordinate.
        eta: (n,) second reference coordinate.
    """
    n = cell.size
    nodes = np.empty((n, 4), dtype=np.int64)
    N, dN, rel = np.zeros((n, 4)), np.zeros((n, 4, 2)), np.zeros((n, 4, 2))
    for p in range(n):
        _add(geo, corners, cell[p], xi[p], eta[p], 1.0, 0.0, 0.0, 0.0, 0.0, nodes, N, dN, rel,
             p, 0)
    return nodes, N, dN
