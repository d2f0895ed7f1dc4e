"""Particle → Q1 projection on an unstructured quadrilateral mesh (lumped / consistent / FCT).

The unstructured counterpart of :class:`mpm.projection.GridProjector` (same method, see its
module docstring): lumped ``h^L = b / M_L``, consistent ``h^H = M_C^{-1} b``, blended as in
FCT by :func:`mpm.projection_blend.pair_blend` (the element antidiffusion
``(M_L^K - M_C^K) h^H`` split into node-pair fluxes: a cell ramped to the lumped projection where
a node undershoots, each flux limited by Zalesak's ratio of the node it takes depth from).

The element matrices ``∫_K φ_a φ_b`` of the bilinear cells are computed once. ``M_C^{-1} b``
is a Jacobi-preconditioned conjugate gradient with a matrix-free, cell-by-cell product (fixed
summation order, serial: deterministic). It runs on the window of :data:`WINDOW_RINGS` node
rings (adjacency through cells) around the nodes with sums, on the cells whose four nodes are
in the window (the principal submatrix of ``M_C``; the solution is taken as 0 outside).
``M_C^{-1}`` decays like about ``0.27^k`` per ring, so the truncation is round-off.
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.mesh import element_masses
from mpm.projection import node_cells
from mpm.projection_blend import blend

__all__ = ["CG_MAX_ITERATIONS", "CG_RTOL", "WINDOW_RINGS", "MeshProjector"]

#: Node rings added around the nodes with sums (the window of the projection).
WINDOW_RINGS = 24
#: CG stops when the residual is below ``CG_RTOL ‖b‖`` (per column) or after the maximum.
CG_RTOL, CG_MAX_ITERATIONS = 1e-15, 500


@numba.njit(cache=True)
def _rings(seeds, offsets, adj, cells, n_nodes, rings):
    """Sorted nodes within ``rings`` rings (breadth first through the cells) of ``seeds``."""
    seen = np.zeros(n_nodes, dtype=np.bool_)
    out = np.empty(n_nodes, dtype=np.int64)
    n = 0
    for s in seeds:
        if not seen[s]:
            seen[s] = True
            out[n] = s
            n += 1
    lo = 0
    for _ in range(rings):
        hi = n
        for t in range(lo, hi):
            for e in range(offsets[out[t]], offsets[out[t] + 1]):
                for q in range(4):
                    b = cells[adj[e], q]
                    if not seen[b]:
                        seen[b] = True
                        out[n] = b
                        n += 1
        if n == hi:
            break
        lo = hi
    return _marked(seen, n)


@numba.njit(cache=True)
def _marked(seen, count):
    """Return the ``count`` indices where ``seen`` is True, increasing (a scan, no sort)."""
    out = np.empty(count, dtype=np.int64)
    n = 0
    for i in range(seen.size):
        if seen[i]:
            out[n] = i
            n += 1
    return out


@numba.njit(cache=True)
def _window_cells(index, offsets, adj, cells, n_nodes):
    """Cells with all nodes in ``index`` (sorted): ``(ids, local)``, local node numbers."""
    local = np.full(n_nodes, -1, dtype=np.int64)
    for t in range(index.size):
        local[index[t]] = t
    inside = np.zeros(cells.shape[0], dtype=np.bool_)
    count = 0
    for t in range(index.size):
        for e in range(offsets[index[t]], offsets[index[t] + 1]):
            c = adj[e]
            if cells[c, 0] == index[t] and min(local[cells[c, 1]], local[cells[c, 2]],
                                               local[cells[c, 3]]) >= 0:
                inside[c] = True  # found once: from its first node
                count += 1
    ids = _marked(inside, count)
    lc = np.empty((count, 4), dtype=np.int64)
    for t in range(count):
        for q in range(4):
            lc[t, q] = local[cells[ids[t], q]]
    return ids, lc


@numba.njit(cache=True)
def _dot(x, y):
    """``x · y`` summed in index order."""
    s = 0.0
    for a in range(x.size):
        s += x[a] * y[a]
    return s


@numba.njit(cache=True)
def _matvec(ids, lc, emass, x, y):
    """``y = M_C x`` on the window, cell by cell in cell order."""
    y[:] = 0.0
    for t in range(ids.size):
        m = emass[ids[t]]
        x0, x1, x2, x3 = x[lc[t, 0]], x[lc[t, 1]], x[lc[t, 2]], x[lc[t, 3]]
        for q in range(4):
            y[lc[t, q]] += m[q, 0] * x0 + m[q, 1] * x1 + m[q, 2] * x2 + m[q, 3] * x3


@numba.njit(cache=True)
def _pcg(ids, lc, emass, b, rtol, max_it):
    """``M_C^{-1} b`` per column by Jacobi-preconditioned CG: ``(x, max iterations)``.

    Three passes over the window per iteration besides the product: ``p·w``; the updates of
    ``x``, ``r``, ``z`` with ``r·z`` and ``r·r``; the new ``p``. Each dot product is summed
    in index order, as :func:`_dot` does (the same bits as one pass per operation).
    """
    n, k = b.shape
    inv = np.zeros(n)
    for t in range(ids.size):
        for q in range(4):
            inv[lc[t, q]] += emass[ids[t], q, q]
    for a in range(n):
        inv[a] = 1.0 / inv[a] if inv[a] > 0.0 else 1.0
    x = np.zeros((n, k))
    r, z, p, w = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    its = 0
    for m in range(k):
        rr = rz = 0.0
        for a in range(n):
            r[a] = b[a, m]
            z[a] = r[a] * inv[a]
            p[a] = z[a]
            rr += r[a] * r[a]
            rz += r[a] * z[a]
        stop = rtol * np.sqrt(rr)
        it = 0
        while it < max_it and np.sqrt(rr) > stop:
            _matvec(ids, lc, emass, p, w)
            alpha = rz / _dot(p, w)
            rz_old, rz, rr = rz, 0.0, 0.0
            for a in range(n):
                x[a, m] += alpha * p[a]
                r[a] -= alpha * w[a]
                z[a] = r[a] * inv[a]
                rz += r[a] * z[a]
                rr += r[a] * r[a]
            beta = rz / rz_old
            for a in range(n):
                p[a] = z[a] + beta * p[a]
            it += 1
        its = max(its, it)
    return x, its


@numba.njit(cache=True)
def _blend(sub, mass, ids, lc, emass, anti, rtol, max_it):
    """Project a window's sums: ``(h, reduced cells, CG iterations)``, ``h[:, 0] >= 0``."""
    high, its = _pcg(ids, lc, emass, sub, rtol, max_it)
    res, limited = blend(sub, mass, high, lc, anti, ids, np.arange(lc.shape[0]),
                         np.arange(sub.shape[0]))
    return res, limited, its


class MeshProjector:
    """Project particle sums onto Q1 on an unstructured quadrilateral mesh (FCT, h >= 0).

    Args:
        cells: (n_cells, 4) node indices in basix's Q1 order (reference corners (0,0),
            (1,0), (0,1), (1,1)).
        coords: (n_nodes, 2) node coordinates.

    Attributes:
        element_mass: (n_cells, 4, 4) consistent element mass matrices.
        lumped_mass: (n_nodes,) ``∫ φ_i`` (element row sums added in cell order).
        limited: Cells whose antidiffusion the last projection reduced (ramped or limited).
        solver_iterations: CG iterations of the last consistent solve (max over columns).
    """

    def __init__(self, cells: np.ndarray, coords: np.ndarray) -> None:
        self.cells = np.ascontiguousarray(cells, dtype=np.int64)
        self.n_nodes = int(coords.shape[0])
        self.element_mass = element_masses(self.cells, np.asarray(coords, dtype=float))
        self.lumped_mass = np.zeros(self.n_nodes)  # np.add.at adds in cell order
        np.add.at(self.lumped_mass, self.cells.ravel(), self.element_mass.sum(axis=2).ravel())
        self._offsets, self._adj = node_cells(self.cells, self.n_nodes)
        # the element antidiffusion matrices M_L^K - M_C^K of the FCT blend
        self._anti = -self.element_mass.copy()
        rows = np.arange(4)
        self._anti[:, rows, rows] += self.element_mass.sum(axis=2)
        self.limited = 0
        self.solver_iterations = 0

    def window(self, nodes: np.ndarray) -> np.ndarray:
        """Sorted nodes within :data:`WINDOW_RINGS` rings of ``nodes`` (global indices)."""
        return _rings(np.asarray(nodes, dtype=np.int64), self._offsets, self._adj, self.cells,
                      self.n_nodes, WINDOW_RINGS)

    def consistent(self, b: np.ndarray, window: np.ndarray | None = None) -> np.ndarray:
        """``M_C^{-1} b`` for (n, k) sums on the window's nodes; (n, k), 0 outside.

        The matrix is the principal submatrix of ``M_C`` on ``window`` (sorted global node
        indices, all nodes by default; each in a cell of the window). Sets
        :attr:`solver_iterations`.
        """
        index = (np.arange(self.n_nodes) if window is None
                 else np.asarray(window, dtype=np.int64))
        ids, lc = self._window_cells(index)
        x, self.solver_iterations = _pcg(ids, lc, self.element_mass,
                                         np.ascontiguousarray(b, dtype=float), CG_RTOL,
                                         CG_MAX_ITERATIONS)
        return x

    def project(self, b: np.ndarray) -> np.ndarray:
        """FCT blend of the lumped and consistent projections of (n_nodes, k) global sums.

        The window is around the nodes where the first column is nonzero; the fields are 0
        outside it. Returns (n_nodes, k) fields, the first (``h``) >= 0.
        """
        out = np.zeros(b.shape)
        nz = np.flatnonzero(b[:, 0])
        if nz.size == 0:
            self.limited = self.solver_iterations = 0
            return out
        index = self.window(nz)
        out[index] = self._blend(index, np.ascontiguousarray(b[index], dtype=float))
        return out

    def project_nodes(self, nodes: np.ndarray, values: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` of one column given on the (sorted) nodes where it is nonzero.

        Returns:
            ``(index, h)``: the window's global nodes (sorted) and the field on them (>= 0;
            zero elsewhere).
        """
        if nodes.size == 0:
            self.limited = self.solver_iterations = 0
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        index = self.window(nodes)
        sub = np.zeros((index.size, 1))
        sub[np.searchsorted(index, nodes), 0] = values
        return index, self._blend(index, sub)[:, 0]

    def _blend(self, index: np.ndarray, sub: np.ndarray) -> np.ndarray:
        """Projection of (n, k) sums on the window ``index``; sets the counts."""
        ids, lc = self._window_cells(index)
        res, self.limited, self.solver_iterations = _blend(
            sub, self.lumped_mass[index], ids, lc, self.element_mass, self._anti, CG_RTOL,
            CG_MAX_ITERATIONS)
        return res

    def _window_cells(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`_window_cells` of the window ``index`` (sorted global nodes)."""
        return _window_cells(index, self._offsets, self._adj, self.cells, self.n_nodes)
