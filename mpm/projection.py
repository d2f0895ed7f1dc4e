"""Particle → Q1 projection of the depth and momenta for outputs and diagnostics.

The particles carry the state; the grid fields ``h, hu, hv`` that every output reads are
projections of the particle volume spread over the particle domains (GIMP weights ``S_ip`` of
:mod:`mpm.gimp`; ``S_ip = N_i(x_p)`` for a domain inside one cell):

* low order (lumped): ``h^L_i = b_i / M_i`` with ``b_i = Σ_p V_p S_ip`` and the lumped Q1
  mass ``M_i = ∫ φ_i`` — non-negative, but smeared by one cell;
* high order (consistent L2): ``M_C h^H = b`` — exact for a nodal field sampled by particles
  at Gauss points (lake at rest to round-off), but it can undershoot at fronts.

They are blended as in flux-corrected transport (:func:`mpm.projection_blend.pair_blend`): the
element antidiffusion ``f_K = (M_L^K - M_C^K) h^H`` is split into node-pair fluxes
``(M_C^K)_ab (h^H_a - h^H_b)``; a cell ramps to the lumped projection as one of its nodes'
consistent depth undershoots zero (by :data:`mpm.projection_blend.RAMP` of the cell's depth),
and each flux is limited by Zalesak's ratio of the node it takes depth from. So ``h >= 0``,
``Σ_i M_i h_i = Σ_p V_p`` exactly, ``h = h^H`` wherever ``h^H >= 0`` everywhere, and the result
is continuous in the particles' data. Further columns (if any) use their pair's factors. The
solver projects ``h`` this way and writes ``hu = h v̄`` with the mass-averaged particle velocity
``v̄_i = Σ m_p v_p S_ip / M_i``
(bounded by the particle velocities, so the output speed never exceeds the particles').

On the structured grid the consistent mass matrix is a tensor product, ``M_C = M_y ⊗ M_x``
with the 1D matrices ``Δ/6 tridiag(1, 4, 1)`` (2 at the ends), so ``M_C^{-1} b`` is two sweeps
of tridiagonal solves (rows, then columns): exact, O(N), no iteration. The projector works on
the global structured node array (index ``j (nx + 1) + i``), which the solver sums over the
ranks once per step; every rank then projects, with no communication, on the flow's support
(:meth:`GridProjector.project_nodes`, :mod:`mpm.projection_support`): the nodes within
:data:`WINDOW_MARGIN` of a node with sums, not the whole grid or the flow's bounding box.
"""

from __future__ import annotations

import numba
import numpy as np

from mpm.projection_blend import blend
from mpm.projection_support import consistent, consistent_on_support, flow_cells, row_spans

__all__ = ["GridProjector", "node_cells", "tridiagonal_mass_solve"]

#: Element mass matrix of a rectangle over |K| (basix dof order (0,0), (1,0), (0,1), (1,1)).
_MASS_REF = np.array([[4, 2, 2, 1], [2, 4, 1, 2], [2, 1, 4, 2], [1, 2, 2, 4]]) / 36.0


@numba.njit(cache=True)
def tridiagonal_mass_solve(rhs, first_end=True, last_end=True):
    """Solve ``M x = rhs`` along the last axis for ``M = tridiag(1, 4, 1)/6`` (2/6 at the ends).

    Args:
        rhs: (m, n) right-hand sides, one per row (n >= 2).
        first_end: The first row is a domain end (2/6 on the diagonal); False: an interior
            row whose left neighbour is outside the window (4/6, its value taken as 0).
        last_end: The same for the last row.

    Returns:
        (m, n) solutions (Thomas algorithm; the matrix is strictly diagonally dominant).
    """
    m, n = rhs.shape
    out = np.empty_like(rhs)
    c = np.empty(n)
    for r in range(m):
        diag = (2.0 if first_end else 4.0) / 6.0
        c[0] = (1.0 / 6.0) / diag
        out[r, 0] = rhs[r, 0] / diag
        for k in range(1, n):
            d = (2.0 if (k == n - 1 and last_end) else 4.0) / 6.0
            denom = d - (1.0 / 6.0) * c[k - 1]
            c[k] = (1.0 / 6.0) / denom
            out[r, k] = (rhs[r, k] - (1.0 / 6.0) * out[r, k - 1]) / denom
        for k in range(n - 2, -1, -1):
            out[r, k] -= c[k] * out[r, k + 1]
    return out


@numba.njit(cache=True)
def node_cells(cells, n_nodes):
    """CSR node → cell adjacency ``(offsets, adj)``, each node's cells in increasing order."""
    offsets = np.zeros(n_nodes + 1, dtype=np.int64)
    for c in range(cells.shape[0]):
        for q in range(4):
            offsets[cells[c, q] + 1] += 1
    for a in range(n_nodes):
        offsets[a + 1] += offsets[a]
    fill = offsets[:-1].copy()
    adj = np.empty(offsets[-1], dtype=np.int64)
    for c in range(cells.shape[0]):
        for q in range(4):
            a = cells[c, q]
            adj[fill[a]] = c
            fill[a] += 1
    return offsets, adj


@numba.njit(cache=True)
def _blend(sub, mass, cells, matrix, wy, wx, ends, area):
    """Project a window's sums (module docstring): ``(h, limited)``, ``h[:, 0] >= 0``."""
    high = consistent(sub, wy, wx, ends, area)
    ids = np.zeros(cells.shape[0], dtype=np.int64)
    return blend(sub, mass, high, cells, matrix.reshape(1, 4, 4), ids,
                 np.arange(cells.shape[0]), np.arange(sub.shape[0]))


@numba.njit(cache=True)
def _blend_on_support(sub, mass, cells, matrix, wy, wx, ends, area, rows, cols):
    """:func:`_blend`, consistent on the flow's support, blended on the flow's cells.

    Returns ``(h, touched nodes, limited)`` (:mod:`mpm.projection_support`).
    """
    lo, hi = row_spans(rows, cols, wy)
    high = consistent_on_support(sub, wy, wx, ends, area, lo, hi, WINDOW_MARGIN)
    start, nodes = flow_cells(rows, cols, wy, wx)
    ids = np.zeros(cells.shape[0], dtype=np.int64)
    res, limited = blend(sub, mass, high, cells, matrix.reshape(1, 4, 4), ids, start, nodes)
    return res, nodes, limited


#: Nodes added around the nodes with particle sums when projecting on a window of the grid.
#: ``M_C^{-1}`` decays like ``(2 - sqrt 3)^k ≈ 0.27^k`` per node, so the window's truncation
#: changes the projection by about ``1e-14`` of the depth (relative): round-off.
WINDOW_MARGIN = 24
#: Window bounds are rounded outwards to multiples of this many nodes (fewer distinct windows).
WINDOW_BLOCK = 8


class GridProjector:
    """Project particle sums onto Q1 (lumped / consistent, FCT-blended for h >= 0).

    Works on global structured node arrays (index ``j (nx + 1) + i``), on the window of the
    grid around the nodes with particle sums (:data:`WINDOW_MARGIN`); zero elsewhere.

    Args:
        cells: ``(nx, ny)`` cells of the rectangle.
        spacing: ``(Δx, Δy)`` [m].
    """

    def __init__(self, cells: tuple[int, int], spacing: tuple[float, float]) -> None:
        nx, ny = cells
        self.shape = (ny + 1, nx + 1)
        self.area = spacing[0] * spacing[1]
        self.matrix = self.area * (np.eye(4) / 4.0 - _MASS_REF)
        self.cells = _grid_cells(nx, ny)
        lumped = np.zeros((ny + 1) * (nx + 1))
        np.add.at(lumped, self.cells.ravel(), 0.25 * self.area)
        self.lumped_mass = lumped
        self.limited = 0
        self._windows: dict[tuple[int, int, int, int], tuple[np.ndarray, ...]] = {}

    def consistent(self, b: np.ndarray, window: tuple[int, int, int, int] | None = None
                   ) -> np.ndarray:
        """``M_C^{-1} b`` for (n, k) nodal sums of the window's nodes; (n, k).

        Args:
            b: (n_window_nodes, k) sums, row-major over the window (all nodes by default).
            window: ``(j0, j1, i0, i1)`` node rows and columns, ends excluded; its sides
                inside the grid are truncated (the solution taken as 0 beyond them).
        """
        ny1, nx1 = self.shape
        j0, j1, i0, i1 = window if window is not None else (0, ny1, 0, nx1)
        ends = np.array([i0 == 0, i1 == nx1, j0 == 0, j1 == ny1])
        return consistent(np.ascontiguousarray(b, dtype=float), j1 - j0, i1 - i0, ends,
                           self.area)

    def project(self, b: np.ndarray) -> np.ndarray:
        """Blend of the lumped and consistent projections of ``b`` (see the module docstring).

        Args:
            b: (n_nodes, k) global nodal sums, first ``Σ_p V_p S_ip`` (then e.g.
                ``Σ_p V_p u_p S_ip``).

        Returns:
            (n_nodes, k) nodal fields, the first (``h``) >= 0.
        """
        window = self.window(b[:, 0])
        out = np.zeros_like(b)
        if window is None:
            return out
        index = self._window_arrays(window)[0]
        out[index] = self._blend(np.ascontiguousarray(b[index], dtype=float), window)
        return out

    def project_nodes(self, nodes: np.ndarray, values: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` of one column given on the nodes where it is not zero (sorted).

        Solved on the flow's support (:mod:`mpm.projection_support`): equal to
        :meth:`project` to about ``1e-14`` of the largest depth, at a cost that follows the
        flow's nodes, not its bounding box.

        Returns:
            ``(index, h)``: the support's nodes (global indices, increasing) and the field
            on them (>= 0; zero elsewhere).
        """
        ny1, nx1 = self.shape
        if nodes.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        j, i = nodes // nx1, nodes % nx1
        window = self._bounds(int(j[0]), int(j[-1]), int(i.min()), int(i.max()))
        j0, j1, i0, i1 = window
        wy, wx = j1 - j0, i1 - i0
        sub = np.zeros((wy * wx, 1))
        sub[(j - j0) * wx + (i - i0), 0] = values
        index, cells = self._window_arrays(window)
        ends = np.array([i0 == 0, i1 == nx1, j0 == 0, j1 == ny1])
        res, touched, self.limited = _blend_on_support(
            sub, self.lumped_mass[index], cells, self.matrix, wy, wx, ends, self.area,
            j - j0, i - i0)
        return index[touched], res[touched, 0]

    def _blend(self, sub: np.ndarray, window: tuple[int, int, int, int]) -> np.ndarray:
        """Projection of a window's sums (row-major, (n, k)); sets :attr:`limited`."""
        ny1, nx1 = self.shape
        j0, j1, i0, i1 = window
        index, cells = self._window_arrays(window)
        ends = np.array([i0 == 0, i1 == nx1, j0 == 0, j1 == ny1])
        res, self.limited = _blend(sub, self.lumped_mass[index], cells, self.matrix,
                                   j1 - j0, i1 - i0, ends, self.area)
        return res

    def window(self, weights: np.ndarray) -> tuple[int, int, int, int] | None:
        """``(j0, j1, i0, i1)``: the nodes with ``weights != 0`` and a margin (None: none)."""
        ny1, nx1 = self.shape
        nz = np.flatnonzero(weights)
        if nz.size == 0:
            return None
        j, i = nz // nx1, nz % nx1
        return self._bounds(int(j.min()), int(j.max()), int(i.min()), int(i.max()))

    def _bounds(self, j_lo: int, j_hi: int, i_lo: int, i_hi: int) -> tuple[int, int, int, int]:
        """Return the window of the nodes in rows ``j_lo..j_hi``, columns ``i_lo..i_hi``."""
        ny1, nx1 = self.shape
        lo_j, hi_j = _block(j_lo - WINDOW_MARGIN, j_hi + WINDOW_MARGIN + 1, ny1)
        lo_i, hi_i = _block(i_lo - WINDOW_MARGIN, i_hi + WINDOW_MARGIN + 1, nx1)
        return lo_j, hi_j, lo_i, hi_i

    def _window_arrays(self, window: tuple[int, int, int, int]) -> tuple[np.ndarray, ...]:
        """Global nodes (row-major) and window-local cells of a window."""
        if window not in self._windows:
            j0, j1, i0, i1 = window
            nx1 = self.shape[1]
            jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1), indexing="ij")
            index = (jj * nx1 + ii).ravel()
            if len(self._windows) > 64:
                self._windows.clear()
            cells = _grid_cells(i1 - i0 - 1, j1 - j0 - 1)
            self._windows[window] = (index, cells)
        return self._windows[window]


def _block(lo: int, hi: int, n: int) -> tuple[int, int]:
    """``[lo, hi)`` rounded outwards to :data:`WINDOW_BLOCK` and clipped to ``[0, n)``."""
    lo = max(0, (lo // WINDOW_BLOCK) * WINDOW_BLOCK)
    hi = min(n, -(-hi // WINDOW_BLOCK) * WINDOW_BLOCK)
    return lo, hi


def _grid_cells(nx: int, ny: int) -> np.ndarray:
    """(nx ny, 4) node indices of the cells of an ``nx × ny`` structured grid (row-major)."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    base = (j * (nx + 1) + i).ravel()
    return np.stack([base, base + 1, base + nx + 1, base + nx + 2], axis=1)
