"""GIMP weights of DAMPM's particle domains on a quadrilateral mesh (issue 17).

A particle's domain is a convex quadrilateral in physical space, cut by the cells it
overlaps (:mod:`mpm.mesh_clip`); the weights are the domain averages of the Q1 basis and its
gradient. See
:func:`domain_basis` and docs/meshes.md, "DAMPM on a gmsh mesh".
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.compiled import without_refcounts
from mpm.mesh_clip import (
    MAX_VISITED,
    cell_polygon,
    clip,
    convex_parts,
    crossed_sides,
    polygon_area,
    quad_points,
)
from mpm.mesh_locate import map_point, tangents
from mpm.weight_reuse import NO_PREVIOUS, copy_entries, write_keys

__all__ = ["MAX_CELLS", "domain_basis", "domain_scratch", "point_basis"]

#: Most cells a particle domain reaches (4 around a regular vertex; up to 6 at a vertex
#: with 5 or 6 cells; more for a domain stretched along the flow before it is split).
MAX_CELLS = 12


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
def _particle_domain(geo, origin, corners, neighbour, k, xi, eta, quad, px, py,
                     nodes, N, dN, rel, work, mom):
    """Fill the scratch rows ``0 .. 4 n - 1`` of one particle; returns ``n`` (cells reached).

    ``quad``: the domain's corner offsets (8); ``work``: the scratch of :func:`domain_basis`.
    A search from the particle's cell over the neighbours across the sides the domain
    crosses (:func:`_cell_moments` per cell); a cell holding a piece gets a slot of moments.
    """
    seen, cross = work[9], work[13]
    if _is_point(quad):
        _add(geo, corners, k, xi, eta, 1.0, px, py, 0.0, 0.0, nodes, N, dN, rel, 0, 0)
        return 1
    seen[0], n_seen, head, slots, total = k, 1, 0, 0, 0.0
    while head < n_seen and slots < MAX_CELLS:
        m = seen[head]
        head += 1
        weight, inside = _cell_moments(geo, origin, k, m, quad, px, py, xi, eta, work, mom,
                                       slots)
        held = weight > 0.0
        total += weight
        if inside and held:  # the domain lies in this cell: no other cell holds any of it
            seen[head - 1], slots = -1 - m, slots + 1
            break
        if held or head == 1:  # the cells beside a piece (or the particle's cell) may hold more
            for e in range(4):
                nb = neighbour[m, e]
                if cross[e] and nb >= 0 and n_seen < MAX_VISITED and not _member(seen, n_seen,
                                                                                   nb):
                    seen[n_seen] = nb
                    n_seen += 1
        if held:
            seen[head - 1], slots = -1 - m, slots + 1  # marks the cell as holding a slot
    if slots == 0:  # the domain misses the mesh (beyond a wall): the point values
        _add(geo, corners, k, xi, eta, 1.0, px, py, 0.0, 0.0, nodes, N, dN, rel, 0, 0)
        return 1
    used = 0
    for v in range(n_seen):
        if seen[v] < 0:
            m = -1 - seen[v]
            seen[v] = m
            _from_moments(geo, corners, m, mom, used, 1.0 / total, px, py,
                          origin[m, 0] - origin[k, 0], origin[m, 1] - origin[k, 1], nodes, N,
                          dN, rel)
            used += 1
    return used


@numba.njit(cache=True, inline="always")
def _cell_moments(geo, origin, k, m, quad, px, py, xi, eta, work, mom, slot):
    """Cut the domain by cell ``m`` and put its pieces' moments in ``slot``.

    Returns the pieces' area (0: none; the slot is then untouched) and whether the domain lies
    inside the cell. Sets ``work``'s side flags (:func:`mpm.mesh_clip.crossed_sides`).
    ``(xi, eta)``: the particle's reference coordinates in its cell ``k``.
    """
    dx, dy, sx, sy, cx, cy, qa, qb, qw, seen, tx, ty, tn, cross = work
    reversed_order = cell_polygon(geo, origin, k, m, cx, cy)
    for c in range(4):
        sx[c], sy[c] = px + quad[2 * c], py + quad[2 * c + 1]
    crossed_sides(sx, sy, cx, cy, reversed_order, cross)
    weight, inside = 0.0, False
    parts = convex_parts(cx, cy, tx, ty, tn)
    # no corner beyond a side of a convex cell: clipping would return the domain as it is
    whole = parts == 1 and not (cross[0] or cross[1] or cross[2] or cross[3])
    for part in range(parts):
        if part == 1:
            for e in range(4):  # a reflex cell: every side may matter
                cross[e] = True
        for c in range(4):
            sx[c], sy[c] = px + quad[2 * c], py + quad[2 * c + 1]
        if polygon_area(sx, sy, 4) < 0.0:
            sx[1], sx[3], sy[1], sy[3] = sx[3], sx[1], sy[3], sy[1]
        n, cut = (4, False) if whole else clip(sx, sy, 4, tx[part], ty[part], tn[part], dx, dy)
        inside = inside or not cut
        if n < 3 or polygon_area(sx, sy, n) <= 0.0:
            continue
        if weight == 0.0:
            for c in range(8):
                mom[slot, c] = 0.0
        for q in range(quad_points(geo, origin, k, m, sx, sy, n, qa, qb, qw, xi, eta)):
            _moments(geo, m, qa[q], qb[q], qw[q], mom, slot)
            weight += qw[q]
    return weight, inside


@numba.njit(cache=True, inline="always")
def _is_point(quad):
    """Whether every corner offset is zero (a point particle)."""
    for c in range(8):
        if quad[c] != 0.0:
            return False
    return True


@numba.njit(cache=True, inline="always")
def _member(seen, n, m):
    """Whether cell ``m`` (or its slot mark ``-1 - m``) is among ``seen[:n]``."""
    for v in range(n):
        if seen[v] == m or seen[v] == -1 - m:
            return True
    return False


@numba.njit(cache=True, inline="always")
def _moments(geo, m, a, b, w, mom, slot):
    """Add a quadrature point ``(a, b)`` of cell ``m``, weight ``w``, to the slot's moments.

    ``Σ w, Σ w a, Σ w b, Σ w a b`` and the same with ``o = w / det J``: the domain's
    ``Σ w N_c`` and ``Σ w ∇N_c`` are linear in them (:func:`_from_moments`), so a point costs
    eight sums instead of twelve weights.
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
        gx, gy = _gradient_sum(geo, m, c, w0, wa, wb, wab)
        dN[0, q0 + c, 0], dN[0, q0 + c, 1] = scale * gx, scale * gy
        nodes[0, q0 + c] = corners[m, c]
    bx, by = ox - px, oy - py
    rel[0, q0, 0], rel[0, q0, 1] = bx, by
    rel[0, q0 + 1, 0], rel[0, q0 + 1, 1] = g0 + bx, g1 + by
    rel[0, q0 + 2, 0], rel[0, q0 + 2, 1] = g2 + bx, g3 + by
    rel[0, q0 + 3, 0] = (g0 + g2 + g4) + bx
    rel[0, q0 + 3, 1] = (g1 + g3 + g5) + by


@numba.njit(cache=True, inline="always")
def _gradient_sum(geo, m, c, w0, wa, wb, wab):
    """``Σ o adj(J)^T ∇_ξ N_c`` of corner ``c`` of cell ``m`` from the sums ``Σ o {1, a, b, ab}``.

    ``∂_ξ N_c = α_c + β_c b``, ``∂_η N_c = γ_c + δ_c a``; ``adj J`` is linear in ``a, b``.
    """
    g0, g1, g2, g3, g4, g5 = geo[m, 0], geo[m, 1], geo[m, 2], geo[m, 3], geo[m, 4], geo[m, 5]
    al = -1.0 if c == 0 else (1.0 if c == 1 else 0.0)
    be = 1.0 if (c == 0 or c == 3) else -1.0
    ga = -1.0 if c == 0 else (1.0 if c == 2 else 0.0)
    de = 1.0 if (c == 0 or c == 3) else -1.0
    return ((g3 * al - g1 * ga) * w0 + (g5 * al - g1 * de) * wa
            + (g3 * be - g5 * ga) * wb + (g5 * be - g5 * de) * wab,
            (g0 * ga - g2 * al) * w0 + (g0 * de - g4 * al) * wa
            + (g4 * ga - g2 * be) * wb + (g4 * de - g4 * be) * wab)


def domain_basis(geo, origin, corners, neighbour, cell, xi, eta, quad, offsets, nodes, S, dS,
                 rel, scratch=None, previous=None, ids=None):
    """Weights of the particle domains: GIMP on a quadrilateral mesh.

    A particle's domain is the convex quadrilateral ``x_p + quad[p]`` (corner offsets
    ``q0x, q0y, .. q3x, q3y``). It is cut by the cells it overlaps and each piece integrated
    with Dunavant's seven-point rule per triangle (:mod:`mpm.mesh_clip`), weights ``w_q`` the
    physical areas, and

        S_ip = Σ_q w_q N_i(x_q) / Σ_q w_q,    ∇S_ip = Σ_q w_q ∇N_i(x_q) / Σ_q w_q:

    the domain averages of GIMP, exact where the cells are parallelograms, continuous as a
    domain moves (a new piece starts with zero area), ``Σ_i S_ip = 1`` and
    ``Σ_i ∇S_ip = 0``. Parts of a domain beyond the mesh are dropped. Domains that tile the
    material (the uniform seeding: the sub-cells) balance the pressure of a uniform layer
    exactly. A point particle (all offsets zero) gets the point values of seed eq. 33.

    The results go to ``offsets`` (n + 1) and the buffers
    ``nodes, S, dS, rel`` (kept by the caller: fresh arrays cost more in page faults
    than the computation): particle ``p``'s entries are ``offsets[p] .. offsets[p + 1] - 1``,
    one per node its domain reaches (the corners of at most :data:`MAX_CELLS` cells).

    ``scratch``: :func:`domain_scratch`, kept by the caller between calls (a new one if None).

    ``previous``: :class:`mpm.weight_reuse.PreviousWeights` of the last call, or None, and
    ``ids`` the particles' ids (to find them in it). A particle whose cell, ``(ξ, η)`` and
    domain have the bits of the same particle then (a particle at rest) gets that call's
    entries copied: the weights are a function of those eleven numbers (and the mesh)
    alone, so the result has the bits of a computation. This call's keys go to
    ``previous.next_keys``; the caller then hands its entries to
    :meth:`~mpm.weight_reuse.PreviousWeights.keep`.

    Returns:
        The number of entries used, or -1 if the buffers are too short (call again with
        longer ones).
    """
    if scratch is None:
        scratch = domain_scratch()
    prev = NO_PREVIOUS if previous is None else previous.loop_arguments(cell.size)
    ident = np.zeros(cell.size, np.int64) if ids is None else ids
    return _domain_loop(geo, origin, corners, neighbour, cell, xi, eta, quad,
                        xi.view(np.int64), eta.view(np.int64), quad.view(np.int64), ident,
                        offsets, nodes, S, dS, rel, *prev, *scratch)


def domain_scratch() -> tuple[np.ndarray, ...]:
    """Return the scratch arrays of :func:`domain_basis`'s loop, reusable from call to call.

    The loop writes every scratch entry before it reads it (zeroing the first four weights of
    each particle itself), so what a previous call left there changes nothing (tested with
    scratch full of garbage).
    """
    w = 4 * MAX_CELLS
    return (np.empty((1, w), dtype=np.int64), np.zeros((1, w)), np.zeros((1, w, 2)),
            np.zeros((1, w, 2)), np.empty((MAX_CELLS, 8)),
            np.empty(16), np.empty(16), np.empty(16), np.empty(16), np.empty(4), np.empty(4),
            np.empty(64), np.empty(64), np.empty(64), np.empty(MAX_VISITED, dtype=np.int64),
            np.empty((2, 4)), np.empty((2, 4)), np.empty(2, dtype=np.int64),
            np.zeros(4, dtype=np.bool_))


def _domain_loop(geo, origin, corners, neighbour, cell, xi, eta, quad, ixi, ieta, iquad, ident,
                 offsets, nodes, S, dS, rel, keys, n_prev, pkeys, poff, pnodes, pS, pdS, prel,
                 snodes, sN, sdN, srel, mom, w0, w1, w2, w3, w4, w5, w6, w7, w8, w9, w10, w11,
                 w12, w13):
    """Run the particles' loop of :func:`domain_basis` on given scratch (it allocates nothing).

    ``ixi, ieta, iquad``: the bits of ``ξ, η`` and the domains (their int64 views), ``ident``
    the ids; ``keys`` receives them with the cell, and a particle found in the last call's
    ``pkeys`` with the same keys (:func:`mpm.weight_reuse.write_keys`) copies that call's
    entries ``poff[q] .. poff[q + 1]``.
    """
    n = cell.size
    cap = nodes.size
    offsets[0] = 0
    work = (w0, w1, w2, w3, w4, w5, w6, w7, w8, w9, w10, w11, w12, w13)
    record, cursor = keys.shape[0] >= n, 0
    for p in range(n):
        k = cell[p]
        q, cursor = write_keys(keys, record, p, k, ixi[p], ieta[p], iquad[p], ident[p], pkeys,
                               n_prev, cursor)
        start = offsets[p]
        if q >= 0:
            count = poff[q + 1] - poff[q]
            if start + count > cap:
                return -1
            copy_entries(poff[q], start, count, pnodes, pS, pdS, prel, nodes, S, dS, rel)
            offsets[p + 1] = start + count
            continue
        px, py = map_point(geo, k, xi[p], eta[p])
        for q in range(4):
            sN[0, q], sdN[0, q, 0], sdN[0, q, 1] = 0.0, 0.0, 0.0
        used = 4 * _particle_domain(geo, origin, corners, neighbour, k, xi[p], eta[p], quad[p],
                                    px, py, snodes, sN, sdN, srel, work, mom)
        if start + used > cap:
            return -1
        offsets[p + 1] = start + _append_unique(start, used, snodes, sN, sdN, srel, nodes, S,
                                                dS, rel)
    return offsets[n]


_domain_loop = without_refcounts(_domain_loop)


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
