"""The active set: the cells and nodes near the flow, where a step does its work (issue 16).

A debris flow or an avalanche wets a few percent of its DEM. The cells with a node within
``rings`` node hops of a node where ``(h, hu, hv) ≠ 0`` are *active*; a scheme whose terms all
carry a factor ``h`` or ``q`` and whose stencil is one cell wide gets exact zeros elsewhere, so
working on the active cells gives the same bits as working on the whole mesh. With a CFL
number ≤ 1 a step wets at most one more ring: the set is rebuilt (collectively) only when a
wet node leaves the inner ``rings - 1`` hops, about every ``rings - 1`` rings the flow
advances.

Hops are grown node-wise with a max over the cells around each node and a max over the ranks
sharing it, so every rank agrees on the status of the cells and nodes it shares; the nodal
sums over the active cells (:meth:`ActiveSet.cell_sum`) are the same bits as
:meth:`fem_runout.mesh.Discretization.cell_sum` on any partition.
"""

from __future__ import annotations

import numba
import numpy as np
from mpi4py import MPI

from fem_runout import cellsum
from fem_runout.mesh import Discretization, GhostReducer, Side
from fem_runout.shared_nodes import SharedRows

__all__ = ["RINGS", "ActiveSet"]

#: Node hops around the wet nodes that the active set covers: the fewest that hold the
#: argument above (a step wets at most one more ring). More rings rebuild less often but
#: visit more dry cells every step: on avaKot (TG2-PC) 4 rings gave 26.3 million active
#: cell-steps and 51 rebuilds, 2 rings 22.6 million and 140 (the same bits; docs/performance.md).
RINGS = 2


@numba.njit(cache=True)
def _grow(offsets, around, cells, flagged, flag, out):
    """``out[i] = max(out[i], flag[j])`` for each node ``i`` sharing a cell with a flagged ``j``.

    The cells around ``j`` are ``around[offsets[j]:offsets[j + 1]]``. With ``flag >= 0`` and
    zero off ``flagged``, the max over the cells around each node of ``flag`` at their nodes,
    visiting only the flagged nodes' cells.
    """
    for j in flagged:
        f = flag[j]
        for p in range(offsets[j], offsets[j + 1]):
            k = around[p]
            for a in range(4):
                i = cells[k, a]
                out[i] = max(out[i], f)


@numba.njit(cache=True)
def _wet_inside(q, rows, inner):
    """Whether every row of ``q`` with a non-zero entry is at a node where ``inner`` holds."""
    for k in range(q.shape[0]):
        if (q[k, 0] != 0.0 or q[k, 1] != 0.0 or q[k, 2] != 0.0) and not inner[rows[k]]:
            return False
    return True


@numba.njit(cache=True)
def _deep_inside(h, rows, inner):
    """Whether every row with ``h > 0`` is at a node where ``inner`` holds."""
    for k in range(h.shape[0]):
        if h[k] > 0.0 and not inner[rows[k]]:
            return False
    return True


@numba.njit(cache=True)
def _mark_cells(offsets, around, flagged, mark):
    """``mark[k] = True`` for every cell around a node of ``flagged``."""
    for j in flagged:
        for p in range(offsets[j], offsets[j + 1]):
            mark[around[p]] = True


class ActiveSet:
    """The cells and nodes within ``rings`` node hops of the flow.

    Attributes:
        mask: (n_cells_local,) bool, the active local cells (owned and ghosts).
        cells: Indices of the active local cells (owned first).
        owned: Indices of the active owned cells.
        wide: Indices of the local cells with a node within ``rings + 1`` hops (the active
            cells and their neighbours).
        nodes: Local nodes within ``rings + 2`` hops: every node of a wide cell.
        rebuilds: Number of rebuilds so far (a version number for caches).

    Args:
        disc: The discretization.
        reducer: Max/min over the ranks sharing a node.
        rings: Node hops covered around the wet nodes (>= 2).
    """

    def __init__(self, disc: Discretization, reducer: GhostReducer, rings: int = RINGS) -> None:
        if rings < 2:
            raise ValueError("the active set needs at least 2 rings")
        self.disc, self._reducer, self.rings = disc, reducer, rings
        self.inner: np.ndarray | None = None  # nodes within rings - 1 hops of the wet ones
        n_cells, n_nodes = disc.cell_nodes.shape[0], disc.coords.shape[0]
        self.mask = np.ones(n_cells, dtype=bool)
        self.cells = np.arange(n_cells)
        self.owned = np.arange(disc.n_owned_cells)
        self.wide = np.arange(n_cells)
        self.nodes = np.arange(n_nodes)
        self.rebuilds = 0
        self.seed: np.ndarray | None = None  # the wet nodes the set was last built around
        self._cache: dict[object, object] = {}
        self._csr: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def active_cells(self) -> int:
        """Number of active local cells."""
        return int(self.cells.size)

    def update(self, q: np.ndarray, nodes: np.ndarray | None = None,
               inside: bool | None = None) -> bool:
        """Rebuild the set if the flow nears its edge (collective).

        Args:
            q: (n_nodes_local, 3) state, or its rows at ``nodes`` (the flow is exactly zero
                elsewhere).
            nodes: Local nodes of the rows of ``q`` (default: all).
            inside: The test's answer over all ranks if the caller has it
                (:meth:`deep_inside` reduced with a message of its own); None: tested here,
                with one reduction.

        Returns:
            True when the set was rebuilt.
        """
        rows = np.arange(q.shape[0]) if nodes is None else nodes
        if inside is None:
            local = self.inner is not None and _wet_inside(q, rows, self.inner)
            inside = self.disc.comm.allreduce(local, op=MPI.LAND)
        if inside:
            return False
        wet = np.zeros(self.disc.coords.shape[0])
        wet[rows[np.any(q != 0.0, axis=1)]] = 1.0
        self.rebuild(wet)
        return True

    def deep_inside(self, h: np.ndarray) -> bool:
        """Whether every node of the set with ``h > 0`` lies within the inner hops (local).

        ``h`` is compact (row ``k`` at node ``nodes[k]``). Where the momenta vanish with the
        depth, as after a transport step (:func:`fem_runout.tg2.compact.settle`), this is
        :meth:`update`'s test on this rank (a state with a negative depth stops the run).
        """
        return self.inner is not None and _deep_inside(h, self.nodes, self.inner)

    def rebuild(self, wet: np.ndarray) -> None:
        """Build the set around the local nodes where ``wet > 0`` (collective).

        :attr:`seed` keeps ``wet``: a checkpoint stores it, so a restarted run works on the
        very set of the uninterrupted one (sums over the flow's dofs then add in the same
        order, and the series match bit for bit).
        """
        self.seed = wet
        hops = [wet]
        for _ in range(self.rings + 2):
            hops.append(self._grow(hops[-1]))
        self.inner = hops[-4] > 0.0
        self.mask = self._cells_around(hops[-3])
        self.cells = np.flatnonzero(self.mask)
        self.owned = self.cells[self.cells < self.disc.n_owned_cells]
        self.wide = np.flatnonzero(self._cells_around(hops[-2]))
        self.nodes = np.flatnonzero(hops[-1] > 0.0)
        self._cache = {}
        self.rebuilds += 1

    def _around(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the local cells around each local node (CSR offsets and cells), built once."""
        if self._csr is None:
            cells = self.disc.cell_nodes
            node = cells.ravel()
            order = np.argsort(node, kind="stable")
            offsets = np.zeros(self.disc.coords.shape[0] + 1, dtype=np.int64)
            np.cumsum(np.bincount(node, minlength=offsets.size - 1), out=offsets[1:])
            self._csr = (offsets, (order // 4).astype(np.int64))
        return self._csr

    def _cells_around(self, flag: np.ndarray) -> np.ndarray:
        """(n_cells_local,) bool: the cells with a node where ``flag > 0``."""
        mark = np.zeros(self.disc.cell_nodes.shape[0], dtype=bool)
        _mark_cells(*self._around(), np.flatnonzero(flag > 0.0), mark)
        return mark

    def _grow(self, flag: np.ndarray) -> np.ndarray:
        """One node hop: the max over the cells around each node, then over the ranks.

        Only the cells around the flagged nodes are visited: a rebuild costs what the flow
        covers, not the mesh.
        """
        out = flag.copy()
        _grow(*self._around(), self.disc.cell_nodes, np.flatnonzero(flag > 0.0), flag, out)
        self._reducer.reduce(out, "max")
        return out

    # -- arrays on the nodes of the set ("compact": row k is local node nodes[k]) ----------
    def _cached(self, key: object, make):
        """Return ``make()``, computed once per rebuild."""
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    @property
    def inverse(self) -> np.ndarray:
        """(n_nodes_local,) row of each local node in the compact arrays, -1 off the set."""
        def make():
            inv = np.full(self.disc.coords.shape[0], -1, dtype=np.int64)
            inv[self.nodes] = np.arange(self.nodes.size)
            return inv
        return self._cached("inverse", make)

    def compact_cells(self, which: str) -> np.ndarray:
        """(n, 4) compact node rows of the ``"owned"`` or ``"cells"`` (local) active cells."""
        return self._cached(("cells", which), lambda: np.ascontiguousarray(
            self.inverse[self.disc.cell_nodes[getattr(self, which)]]))

    @property
    def reducer(self) -> SharedRows:
        """Exchanges of compact arrays over the set's shared nodes (max/min, sums)."""
        return self._cached("reducer", lambda: self._reducer.on(self.nodes))

    @property
    def n_owned_nodes(self) -> int:
        """Number of owned nodes among :attr:`nodes` (they come first)."""
        return self._cached("owned_nodes", lambda: int(np.searchsorted(
            self.nodes, self.disc.n_owned_nodes)))

    def sides(self) -> list[Side]:
        """Return the boundary sides with compact node rows (nodes off the set left out)."""
        def make():
            out = []
            for side in self.disc.sides:
                pos = self.inverse[side.nodes]
                ok = pos >= 0
                out.append(side.take(ok, pos[ok]))
            return out
        return self._cached("sides", make)

    def cell_sum(self, contrib: np.ndarray, also_max: np.ndarray | None = None) -> np.ndarray:
        """``Σ_K contrib[K, a]`` per node of the set over the active owned cells (compact).

        The same bits as :meth:`fem_runout.mesh.Discretization.cell_sum` of the whole mesh with
        zeros on the other cells, on any partition: the same slots summed in the same order.

        Args:
            contrib: (n_active_owned, 4) or (n_active_owned, 4, bs), rows in :attr:`owned`'s
                order.
            also_max: (k, n_set_nodes) compact values reduced in place (max over the ranks
                sharing a node) in the same exchange.

        Returns:
            (n_set_nodes,) or (n_set_nodes, bs), row k for local node ``nodes[k]`` (owned and
            ghosts).
        """
        bs = 1 if contrib.ndim == 2 else contrib.shape[2]
        src = self._sources()
        flat = np.ascontiguousarray(contrib.reshape(-1, bs))
        out = np.empty((self.nodes.size, bs))
        cellsum.gather_total(src, flat, out)
        self.reducer.cell_sum(src, flat, out, also_max)  # the shared nodes' totals over the ranks
        return out[:, 0] if contrib.ndim == 2 else out

    def _sources(self) -> np.ndarray:
        """Slot sources (:func:`fem_runout.cellsum.sources`) of the set's nodes, per rebuild."""
        def make():
            d, idx = self.disc, self.owned
            src = cellsum.sources(d.cell_nodes[idx], d.slot[idx], d.coords.shape[0], d.n_slots)
            return np.ascontiguousarray(src[self.nodes])
        return self._cached("sources", make)
