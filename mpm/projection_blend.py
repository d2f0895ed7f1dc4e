"""The FCT blend of the particle projections: non-negative, conservative, continuous in the data.

:class:`mpm.projection.GridProjector` and :class:`mpm.mesh_projection.MeshProjector` compute the
lumped projection ``h^L = b / M_L`` and the consistent one ``h^H = M_C^{-1} b`` of the particle
sums ``b_i = Σ_p V_p S_ip``; :func:`blend` turns the two into the output depth (and further
columns) with :func:`pair_blend`.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["RAMP", "blend", "pair_blend"]

#: A cell's antidiffusion ramps to zero as the consistent depth of one of its nodes falls
#: below zero, reaching it at ``RAMP`` times the cell's largest lumped depth.
RAMP = 0.01


@numba.njit(cache=True, inline="always")
def _cell_factor(h0, h1, h2, h3, depth):
    """Return ``α_K = clip(1 - U_K / (RAMP H_K), 0, 1)`` of a cell.

    ``U_K`` is the largest undershoot of ``h^H`` (``h0 .. h3``) below zero at the cell's nodes,
    ``H_K = depth`` its largest lumped depth (0 for a cell without depth: its fluxes take
    depth from nowhere).
    """
    under = max(max(0.0, max(-h0, -h1)), max(-h2, -h3))
    if depth <= 0.0:
        return 0.0
    return max(0.0, 1.0 - under / (RAMP * depth))


@numba.njit(cache=True, inline="always")
def _cell_fluxes(cells, mats, ids, high, c):
    """Return the first column's six pair fluxes of cell ``c`` and its four ``h^H``."""
    e = ids[c]
    h0, h1 = high[cells[c, 0], 0], high[cells[c, 1], 0]
    h2, h3 = high[cells[c, 2], 0], high[cells[c, 3], 0]
    return (mats[e, 0, 1] * (h1 - h0), mats[e, 0, 2] * (h2 - h0), mats[e, 0, 3] * (h3 - h0),
            mats[e, 1, 2] * (h2 - h1), mats[e, 1, 3] * (h3 - h1), mats[e, 2, 3] * (h3 - h2),
            h0, h1, h2, h3)


@numba.njit(cache=True, inline="always")
def _loss(f, la, lb):
    """Add a pair flux ``f`` (a gets ``+f``, b ``-f``) to the losses of a and b."""
    if f > 0.0:
        return la, lb - f
    return la + f, lb


@numba.njit(cache=True, inline="always")
def _cut(f, alpha, ra, rb):
    """Return the share of a pair flux ``f`` (a gets ``+f``) the factors take off."""
    return 1.0 - alpha * (rb if alpha * f > 0.0 else ra)


@numba.njit(cache=True, inline="always")
def _more_columns(acc, cells, mats, ids, high, c, w01, w02, w03, w12, w13, w23):
    """Add the pair fluxes of cell ``c`` in the columns after the first, times ``w_ab``."""
    e = ids[c]
    n0, n1, n2, n3 = cells[c, 0], cells[c, 1], cells[c, 2], cells[c, 3]
    for m in range(1, acc.shape[1]):
        h0, h1, h2, h3 = high[n0, m], high[n1, m], high[n2, m], high[n3, m]
        g01, g02 = w01 * mats[e, 0, 1] * (h1 - h0), w02 * mats[e, 0, 2] * (h2 - h0)
        g03, g12 = w03 * mats[e, 0, 3] * (h3 - h0), w12 * mats[e, 1, 2] * (h2 - h1)
        g13, g23 = w13 * mats[e, 1, 3] * (h3 - h1), w23 * mats[e, 2, 3] * (h3 - h2)
        acc[n0, m] += g01 + g02 + g03
        acc[n1, m] += g12 + g13 - g01
        acc[n2, m] += g23 - g02 - g12
        acc[n3, m] -= g03 + g13 + g23


@numba.njit(cache=True)
def _full_fluxes(cells, mats, ids, low, high, start, acc):
    """Add every pair flux of the ``start`` cells with depth to ``acc`` in full: ``(α_K, P⁻)``.

    Returns each start cell's factor ``α_K`` (``-1``: a cell without lumped depth, skipped)
    and the (ramped) first-column fluxes leaving each node, ``P⁻ <= 0``. A cell without
    lumped depth has ``α_K = 0``: its fluxes would be added and taken off again in full, a
    net zero but for round-off (:func:`pair_blend`), so they are not formed at all.
    """
    alpha = np.empty(start.size)
    leave = np.zeros(low.shape[0])
    for t in range(start.size):
        c = start[t]
        n0, n1, n2, n3 = cells[c, 0], cells[c, 1], cells[c, 2], cells[c, 3]
        depth = max(max(low[n0, 0], low[n1, 0]), max(low[n2, 0], low[n3, 0]))
        if not depth > 0.0:
            alpha[t] = -1.0
            continue
        f01, f02, f03, f12, f13, f23, h0, h1, h2, h3 = _cell_fluxes(cells, mats, ids, high, c)
        acc[n0, 0] += f01 + f02 + f03
        acc[n1, 0] += f12 + f13 - f01
        acc[n2, 0] += f23 - f02 - f12
        acc[n3, 0] -= f03 + f13 + f23
        al = alpha[t] = _cell_factor(h0, h1, h2, h3, depth)
        l0, l1 = _loss(al * f01, 0.0, 0.0)
        l0, l2 = _loss(al * f02, l0, 0.0)
        l0, l3 = _loss(al * f03, l0, 0.0)
        l1, l2 = _loss(al * f12, l1, l2)
        l1, l3 = _loss(al * f13, l1, l3)
        l2, l3 = _loss(al * f23, l2, l3)
        leave[n0] += l0
        leave[n1] += l1
        leave[n2] += l2
        leave[n3] += l3
        if acc.shape[1] > 1:
            _more_columns(acc, cells, mats, ids, high, c, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    return alpha, leave


@numba.njit(cache=True)
def _take_off(cells, mats, ids, high, start, alpha, ratio, acc):
    """Subtract from ``acc`` what the factors take off the fluxes; return the cells reduced."""
    limited = 0
    for t in range(start.size):
        c = start[t]
        n0, n1, n2, n3 = cells[c, 0], cells[c, 1], cells[c, 2], cells[c, 3]
        r0, r1, r2, r3, al = ratio[n0], ratio[n1], ratio[n2], ratio[n3], alpha[t]
        if al < 0.0 or (al == 1.0 and min(min(r0, r1), min(r2, r3)) == 1.0):
            continue  # skipped (no depth), or nothing to take off
        limited += 1
        f01, f02, f03, f12, f13, f23 = _cell_fluxes(cells, mats, ids, high, c)[:6]
        q01, q02, q03 = _cut(f01, al, r0, r1), _cut(f02, al, r0, r2), _cut(f03, al, r0, r3)
        q12, q13, q23 = _cut(f12, al, r1, r2), _cut(f13, al, r1, r3), _cut(f23, al, r2, r3)
        g01, g02, g03 = q01 * f01, q02 * f02, q03 * f03
        g12, g13, g23 = q12 * f12, q13 * f13, q23 * f23
        acc[n0, 0] -= g01 + g02 + g03
        acc[n1, 0] -= g12 + g13 - g01
        acc[n2, 0] -= g23 - g02 - g12
        acc[n3, 0] += g03 + g13 + g23
        if acc.shape[1] > 1:
            _more_columns(acc, cells, mats, ids, high, c, -q01, -q02, -q03, -q12, -q13, -q23)
    return limited


@numba.njit(cache=True)
def pair_blend(cells, mats, ids, sub, low, high, mass, start, nodes):
    """``h = h^L + M_L^{-1} Σ_K α_K Σ_pairs R_ab f_ab``: ``h >= 0``, continuous in the data.

    With row-sum lumping the rows of ``M_L^K - M_C^K`` sum to zero, so the element
    antidiffusion ``f_K = (M_L^K - M_C^K) h^H`` is a sum of antisymmetric node-pair fluxes
    ``f_ab = (M_C^K)_ab (h^H_a - h^H_b)`` (``a`` gets ``+f_ab``, ``b`` gets ``-f_ab``). Two factors:

    * per cell, ``α_K`` (:func:`_cell_factor`) ramps the cell from the consistent to the
      lumped projection as the consistent depth of one of its nodes falls below zero, by
      ``RAMP`` times the cell's largest lumped depth: the continuous form of switching off the
      cells around an undershoot, which keeps a particle front's depth from breaking into
      holes where the particles are sparse;
    * per pair, Zalesak's ratio of the node the flux takes depth from (first column),
      ``R_i = min(1, b_i / -P⁻_i)`` with ``P⁻_i`` the (ramped) fluxes leaving ``i``, so
      ``M_i h_i >= b_i + R_i P⁻_i >= 0`` (``b_i = M_i h^L_i``).

    ``Σ_i M_i h_i = Σ_i b_i`` for any factors. Where ``h^H >= 0`` everywhere, ``α_K = 1`` and no
    ratio is below 1 (``-P⁻_i <= (M_C h^H)_i = b_i``): the consistent projection, a lake at rest
    to round-off. Both factors are continuous in the data, and each limited flux too (``|f| <=
    -P⁻`` at its source; both branches vanish where ``f`` changes sign), as in TG2-PC's limiter
    (:mod:`fem_runout.tg2.fct`): the outputs no longer jump when a node's undershoot crosses a
    threshold. Further columns get their pair's factors. Used by both projectors.

    Args:
        cells: (n_cells, 4) window-local nodes of the window's cells.
        mats: (m, 4, 4) the matrices ``M_L^K - M_C^K``; cell ``c`` uses ``mats[ids[c]]``.
        ids: (n_cells,) matrix of each cell.
        sub: (n, k) the sums ``b`` (first column ``Σ_p V_p S_ip >= 0``).
        low: (n, k) low-order (lumped) projection ``b / M_L``.
        high: (n, k) high-order (consistent) projection.
        mass: (n,) lumped mass.
        start: The cells to visit, increasing: at least every cell with lumped depth (the
            others, if any, are skipped: their factor is 0).
        nodes: The nodes of those cells, increasing (``h = 0`` elsewhere).

    Returns:
        ``(h, limited)``: (n, k) blended fields and the number of cells whose antidiffusion
        was reduced (ramped or limited).
    """
    n, k = low.shape
    acc = np.zeros((n, k))
    alpha, leave = _full_fluxes(cells, mats, ids, low, high, start, acc)
    ratio = np.ones(n)
    for i in nodes:
        room = max(sub[i, 0], 0.0)
        if room < -leave[i]:
            ratio[i] = room / -leave[i]
    limited = _take_off(cells, mats, ids, high, start, alpha, ratio, acc)
    out = np.zeros(low.shape)
    for a in nodes:
        for m in range(k):
            out[a, m] = low[a, m] + acc[a, m] / mass[a]
        out[a, 0] = max(out[a, 0], 0.0)  # round-off of the bound
    return out, limited


@numba.njit(cache=True)
def blend(sub, mass, high, cells, mats, ids, start, nodes):
    """Blend the lumped projection ``sub / mass`` with ``high`` (:func:`pair_blend`), ``h >= 0``.

    Returns ``(h, limited)`` (the arguments as :func:`pair_blend`'s; ``sub`` is zero off
    ``nodes``).
    """
    low = np.zeros(sub.shape)
    for a in nodes:
        for m in range(sub.shape[1]):
            low[a, m] = sub[a, m] / mass[a]
    return pair_blend(cells, mats, ids, sub, low, high, mass, start, nodes)
