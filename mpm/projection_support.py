"""The grid projection on the flow's support instead of its bounding box (issue 16).

:class:`mpm.projection.GridProjector` solves ``M_C h^H = b`` by tridiagonal sweeps (rows, then
columns) on a window of the grid: the box around the nodes with particle sums, widened by
:data:`mpm.projection.WINDOW_MARGIN` nodes, beyond which the solution is taken as zero
(``M_C^{-1}`` decays like ``0.27^k`` per node: round-off at 24 nodes). A flow running down a
diagonal valley fills a few percent of its box, and the box's sweeps, antidiffusion and output
writes cost per node of the box on every rank and every step (about 1 ms per step on avaKot,
the same on 1 and 2 ranks).

Here each row is solved only on its span of nodes with sums widened by the margin, and each
column only on the rows within the margin of a span, counted as ``|Δi| + |Δj|`` (a span
reached at ``d`` columns adds ``margin - d`` rows on each side): the same truncation as the
window's, ``0.27^margin``, at the margin of the flow instead of its box. The two projections
differ by the truncation, about ``1e-14`` of the largest depth (tested). On avaKot's 10 m grid
the support has 0.6 times the window's nodes and the projection cost 0.85 ms per step instead
of 1.2 ms.

The blend (:func:`mpm.projection_blend.pair_blend`) forms fluxes only in the cells with lumped
depth, which touch a node with sums (:func:`flow_cells`): the consistent depth is needed on the
whole support, but a cell without lumped depth has no antidiffusion (its factor is 0). The
result is returned on the nodes of those cells, zero elsewhere. On avaKot (session 51) the
support's cells were 5–7 times the flow's, and blending on the flow's cells took the
projection from 1.17 to 0.63 ms per step; the depths moved by round-off (1.8e-17 of the
largest), and the nodes with a nonzero depth, which the outputs read, went from 4 893 to
1 615 (the former ring of round-off values beyond the flow is now exactly zero).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["consistent", "consistent_on_support", "flow_cells", "row_spans"]


@numba.njit(cache=True)
def consistent(b, wy, wx, ends, area):
    """``M_C^{-1} b`` on a (wy × wx) window, b row-major (wy wx, k): rows, then columns."""
    k, size = b.shape[1], wy * wx
    x = np.empty(k * size)
    for a in range(size):
        for m in range(k):
            x[m * size + a] = b[a, m]
    cx, dx = _factors(wx, ends[0])
    cy, dy = _factors(wy, ends[2])
    last_x, last_y = _last_inverse(cx, dx, wx, ends[1]), _last_inverse(cy, dy, wy, ends[3])
    for m in range(k):
        for r in range(wy):
            _solve(x, m * size + r * wx, 1, wx, cx, dx, last_x)
        for i in range(wx):
            _solve(x, m * size + i, wx, wy, cy, dy, last_y)
    out = np.empty((size, k))
    scale = 1.0 / area
    for a in range(size):
        for m in range(k):
            out[a, m] = x[m * size + a] * scale
    return out


@numba.njit(cache=True)
def row_spans(rows, cols, wy):
    """``(lo, hi)`` per window row: the columns of its listed nodes, ``[lo, hi)`` (-1: none)."""
    lo = np.full(wy, -1, dtype=np.int64)
    hi = np.full(wy, -1, dtype=np.int64)
    for t in range(rows.size):
        r, i = rows[t], cols[t]
        if lo[r] < 0 or i < lo[r]:
            lo[r] = i
        if i + 1 > hi[r]:
            hi[r] = i + 1
    return lo, hi


@numba.njit(cache=True)
def _factors(n, first_end):
    """Thomas factors ``(c, 1/denom)`` of lines of up to ``n`` nodes with interior diagonals.

    The factors of every line of a direction are the same: no division per node. A line
    ending at a domain end replaces its last inverse (:func:`_last_inverse`).
    """
    c, inv = np.empty(max(n, 1)), np.empty(max(n, 1))
    denom = (2.0 if first_end else 4.0) / 6.0
    c[0], inv[0] = (1.0 / 6.0) / denom, 1.0 / denom
    for t in range(1, n):
        denom = 4.0 / 6.0 - (1.0 / 6.0) * c[t - 1]
        c[t], inv[t] = (1.0 / 6.0) / denom, 1.0 / denom
    return c, inv


@numba.njit(cache=True, inline="always")
def _last_inverse(c, inv, n, last_end):
    """``1/denom`` of a line's last node (2/6 on the diagonal at a domain end)."""
    if n < 2 or not last_end:  # (a one-node line never reads it)
        return inv[max(n, 1) - 1]
    return 1.0 / (2.0 / 6.0 - (1.0 / 6.0) * c[n - 2])


@numba.njit(cache=True)
def _solve(x, start, step, n, c, inv, last):
    """Tridiagonal mass solve in place on ``x[start + t step]``, ``t < n``.

    ``c, inv``: the factors (:func:`_factors`); ``last``: the last node's inverse.
    """
    x[start] = x[start] * inv[0]
    for t in range(1, n):
        iv = last if t == n - 1 else inv[t]
        x[start + t * step] = (x[start + t * step] - (1.0 / 6.0) * x[start + (t - 1) * step]
                               ) * iv
    for t in range(n - 2, -1, -1):
        x[start + t * step] -= c[t] * x[start + (t + 1) * step]


@numba.njit(cache=True)
def _column_ranges(lo, hi, wy, wx, margin):
    """Rows ``[clo, chi)`` each column is solved on (``clo = chi = 0``: none).

    Column ``i`` takes every row ``r`` whose widened span reaches it, at ``d`` columns from
    the span, with ``margin - d`` rows on each side: the support is the set within ``margin``
    nodes (``|Δi| + |Δj|``) of a span, where ``M_C^{-1}`` has decayed to ``0.27^margin``.
    """
    clo = np.full(wx, wy, dtype=np.int64)
    chi = np.zeros(wx, dtype=np.int64)
    for r in range(wy):
        if lo[r] < 0:
            continue
        for i in range(max(0, lo[r] - margin), min(wx, hi[r] + margin)):
            d = lo[r] - i if i < lo[r] else (i - hi[r] + 1 if i >= hi[r] else 0)
            clo[i] = min(clo[i], r - (margin - d))
            chi[i] = max(chi[i], r + 1 + (margin - d))
    for i in range(wx):
        if chi[i] == 0:
            clo[i] = 0
        else:
            clo[i], chi[i] = max(0, clo[i]), min(wy, chi[i])
    return clo, chi


@numba.njit(cache=True)
def consistent_on_support(b, wy, wx, ends, area, lo, hi, margin):
    """``M_C^{-1} b`` on a window solved line by line on the flow's support (module doc).

    Args:
        b: (wy wx, k) sums, row-major over the window, zero outside the rows' spans.
        wy: Window rows.
        wx: Window columns.
        ends: The window's left, right, bottom, top sides are domain ends.
        area: Cell area.
        lo: (wy,) first column of each row's span (-1: empty row).
        hi: (wy,) end of each row's span.
        margin: Nodes added on each side of a span and of a column's rows.

    Returns:
        (wy wx, k) solution, zero off the support (the columns' ranges of
        :func:`_column_ranges`).
    """
    k, size = b.shape[1], wy * wx
    x = np.zeros(k * size)
    ce, ie = _factors(wx, True)
    cn, inn = _factors(wx, False)
    clo, chi = _column_ranges(lo, hi, wy, wx, margin)
    for m in range(k):
        for r in range(wy):
            if lo[r] < 0:
                continue
            s, e = max(0, lo[r] - margin), min(wx, hi[r] + margin)
            for i in range(s, e):
                x[m * size + r * wx + i] = b[r * wx + i, m]
            first = ends[0] and s == 0
            c, inv = (ce, ie) if first else (cn, inn)
            last = _last_inverse(c, inv, e - s, ends[1] and e == wx)
            _solve(x, m * size + r * wx + s, 1, e - s, c, inv, last)
    cye, iye = _factors(wy, True)
    cyn, iyn = _factors(wy, False)
    for m in range(k):
        for i in range(wx):
            if chi[i] == 0:
                continue
            first = ends[2] and clo[i] == 0
            c, inv = (cye, iye) if first else (cyn, iyn)
            n = chi[i] - clo[i]
            last = _last_inverse(c, inv, n, ends[3] and chi[i] == wy)
            _solve(x, m * size + clo[i] * wx + i, wx, n, c, inv, last)
    high = np.zeros((size, k))
    scale = 1.0 / area
    for i in range(wx):
        for r in range(clo[i], chi[i]):
            for m in range(k):
                high[r * wx + i, m] = x[m * size + r * wx + i] * scale
    return high


@numba.njit(cache=True)
def flow_cells(rows, cols, wy, wx):
    """Cells touching the listed nodes and the nodes of those cells, both row-major.

    The blend (:func:`mpm.projection_blend.pair_blend`) forms fluxes only in cells with
    lumped depth, which touch a node with sums: these cells, not the whole support.

    Args:
        rows: Window rows of the nodes with sums.
        cols: Their window columns.
        wy: Window rows.
        wx: Window columns.

    Returns:
        ``(cells, nodes)``: window cell indices ``r (wx - 1) + i`` and window node indices.
    """
    hit = np.zeros((wy - 1) * (wx - 1), dtype=np.bool_)
    for t in range(rows.size):
        r, i = rows[t], cols[t]
        for cr in range(max(r - 1, 0), min(r + 1, wy - 1)):
            for ci in range(max(i - 1, 0), min(i + 1, wx - 1)):
                hit[cr * (wx - 1) + ci] = True
    cells = np.flatnonzero(hit)
    mark = np.zeros(wy * wx, dtype=np.bool_)
    for c in cells:
        r, i = c // (wx - 1), c % (wx - 1)
        mark[r * wx + i] = mark[r * wx + i + 1] = True
        mark[(r + 1) * wx + i] = mark[(r + 1) * wx + i + 1] = True
    return cells, np.flatnonzero(mark)
