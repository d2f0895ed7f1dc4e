"""Exchanges on the shared nodes of a node subset: a step's messages follow the flow (issue 16).

The active set (:mod:`fem_runout.active`) holds a few percent of the mesh's nodes, and so of
the nodes that ranks share. DOLFINx's scatters and a :class:`~fem_runout.mesh.GhostReducer`
move every ghost of the whole vectors, so their cost grows with the partition's cut, not with
the flow: a partition into stripes that balances a moving flow (:mod:`fem_runout.partition`)
multiplied the ghosts and made every exchange dearer. :class:`SharedRows` exchanges only the
set's shared nodes, in compact arrays (row ``k`` is the set's node ``nodes[k]``), with one
``Alltoallv`` per exchange: every rank sends its part to every rank sharing the node and
folds what it receives as they do (before session 37 the owners folded and sent the result
back, two messages and twice the waits per exchange):

- :meth:`SharedRows.reduce`: max or min over the ranks sharing a node (exact);
- :meth:`SharedRows.cell_sum`: the nodal sums of cell contributions with the slots of
  :mod:`fem_runout.cellsum` (each slot filled by one cell over all ranks, so adding the ranks'
  slots is exact and the total, in a fixed order, is the same bits on any partition).

Every rank sharing a node must agree that it is in the set (the active set's hops are reduced
over the ranks, so they do); then the two ends list the same nodes in the same (global)
order (:func:`sharing_ranks`).
"""

from __future__ import annotations

import numba
import numpy as np
from mpi4py import MPI

__all__ = ["SharedRows", "sharing_ranks"]


@numba.njit(cache=True)
def _take(values, rows, out):
    """``out[m, r] = values[r, rows[m]]``."""
    for m in range(rows.size):
        for r in range(values.shape[0]):
            out[m, r] = values[r, rows[m]]


@numba.njit(cache=True)
def _fold(values, rows, recv, is_max):
    """``values[r, rows[m]] = max (or min) of itself and recv[m, r]``; NaN wins (any order)."""
    for m in range(rows.size):
        i = rows[m]
        for r in range(values.shape[0]):
            v, x = recv[m, r], values[r, i]
            if x != x:
                continue
            if v != v or ((v > x) if is_max else (v < x)):
                values[r, i] = v


@numba.njit(cache=True)
def _pack(src, flat, rows, vals, send):
    """Row ``m`` of ``send``: the slots of node ``rows[m]``, then its ``k`` values of ``vals``.

    Slot ``s`` is ``flat[src[rows[m], s]]`` (0 where empty), slot-major (``s * bs + c``);
    ``vals`` is (k, n).
    """
    n_slots, bs = src.shape[1], flat.shape[1]
    width = n_slots * bs
    for m in range(rows.size):
        i = rows[m]
        for s in range(n_slots):
            j = src[i, s]
            for c in range(bs):
                send[m, s * bs + c] = flat[j, c] if j >= 0 else 0.0
        for r in range(vals.shape[0]):
            send[m, width + r] = vals[r, i]


@numba.njit(cache=True)
def _unpack(send, recv, rows, uniq, where, bs, acc, out, vals):
    """Shared rows: own slots plus the received ones, totalled in the slots' order.

    ``acc[u]`` takes the slots of row ``uniq[u]`` (this rank's, from ``send``), ``recv[m]`` is
    added to ``acc[where[m]]`` (each slot is non-zero on one rank only: exact), and
    ``out[uniq[u], c] = ((0 + b_0) + b_1) + ...`` as :func:`fem_runout.cellsum.gather_total`
    sums on one rank. The received values after the slots are folded into ``vals`` by max
    (:func:`_fold`).
    """
    width = acc.shape[1]
    n_slots = width // bs
    for m in range(where.size):  # own slots first (a row sent to two ranks: the same slots)
        for w in range(width):
            acc[where[m], w] = send[m, w]
    for m in range(where.size):
        u = where[m]
        for w in range(width):
            acc[u, w] += recv[m, w]
    for u in range(uniq.size):
        for c in range(bs):
            total = 0.0
            for s in range(n_slots):
                total = total + acc[u, s * bs + c]
            out[uniq[u], c] = total
    for m in range(rows.size):
        i = rows[m]
        for r in range(vals.shape[0]):
            v, x = recv[m, width + r], vals[r, i]
            if x != x:
                continue
            if v != v or v > x:
                vals[r, i] = v


def _displacements(counts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def sharing_ranks(comm: MPI.Comm, n_owned: int, ghosts: np.ndarray, owners: np.ndarray,
                  first: int) -> tuple[np.ndarray, np.ndarray]:
    """Local nodes shared with each other rank, grouped by rank, in global order (collective).

    Rank ``p`` shares a node when it holds it: it owns it, holds it as a ghost of this rank's,
    or holds as a ghost a node this rank also holds as a ghost (a node where three ranks' cells
    meet; its owner tells the holders about each other). Both ends of a pair list the same
    nodes in the same (global) order, so one ``Alltoallv`` pairs the rows. Called once per mesh.

    Args:
        comm: The mesh's communicator.
        n_owned: Owned nodes of this rank (local ``0 .. n_owned - 1``).
        ghosts: (n_ghosts,) global indices of the ghost nodes (local ``n_owned + k``).
        owners: (n_ghosts,) their owner ranks.
        first: Global index of the first owned node.

    Returns:
        ``(nodes, counts)``: local nodes grouped by rank, and how many each rank shares.
    """
    size = comm.size
    ghosts, owners = np.asarray(ghosts, np.int64), np.asarray(owners, np.int64)
    order = np.argsort(owners, kind="stable")
    parts = np.split(ghosts[order], np.cumsum(np.bincount(owners, minlength=size))[:-1])
    held = [np.asarray(g, np.int64) - first for g in comm.alltoall(parts)]  # owned, held by p
    loc = np.concatenate(held)
    src = np.repeat(np.arange(size), [h.size for h in held])
    o = np.argsort(loc, kind="stable")
    loc, src = loc[o], src[o]
    tell: list[list[tuple[int, int]]] = [[] for _ in range(size)]
    for s, e in _runs(loc):  # nodes held as ghosts by two or more ranks
        for a in range(s, e):
            tell[src[a]] += [(int(loc[s]) + first, int(src[b])) for b in range(s, e) if b != a]
    told = np.concatenate([np.asarray(t, np.int64).reshape(-1, 2)
                           for t in comm.alltoall([np.asarray(t, np.int64) for t in tell])])
    by_global = np.argsort(ghosts, kind="stable")
    also = n_owned + by_global[np.searchsorted(ghosts[by_global], told[:, 0])]
    glob = np.concatenate([first + np.arange(n_owned), ghosts])
    groups = []
    for p in range(size):
        mine = np.unique(np.concatenate([held[p], n_owned + np.flatnonzero(owners == p),
                                         also[told[:, 1] == p]]))
        groups.append(mine[np.argsort(glob[mine], kind="stable")])
    return np.concatenate(groups).astype(np.int64), np.array([g.size for g in groups], np.int64)


def _runs(sorted_values: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` of the runs of equal values at least two long."""
    if sorted_values.size == 0:
        return []
    cut = np.flatnonzero(sorted_values[1:] != sorted_values[:-1]) + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut, [sorted_values.size]])
    return [(int(s), int(e)) for s, e in zip(starts, ends, strict=True) if e - s > 1]


class SharedRows:
    """Exchanges over the shared nodes of a set of local nodes (compact arrays).

    Each rank sends every rank sharing a node its own part (slot contributions, values) and
    folds what it receives the same way the others do: one ``Alltoallv`` per exchange, and
    every rank holding a node ends with the same bits.

    Args:
        comm: The mesh's communicator.
        rows: Compact rows of the set's shared nodes, grouped by the rank they are shared
            with (a row appears once per such rank), in the order both ends agree on
            (:func:`sharing_ranks`).
        counts: (size,) how many rows each rank shares.
    """

    def __init__(self, comm: MPI.Comm, rows: np.ndarray, counts: np.ndarray) -> None:
        self.comm = comm
        self.rows = np.ascontiguousarray(rows, dtype=np.int64)
        self._counts = np.asarray(counts, np.int64)
        self._uniq, self._where = np.unique(self.rows, return_inverse=True)
        self._plans: dict[int, tuple] = {}
        self._acc: dict[int, np.ndarray] = {}  # the shared rows' slots (cell_sum), by width
        self._no_values = np.empty((0, 0))

    @property
    def serial(self) -> bool:
        """True on one rank (nothing to exchange)."""
        return self.comm.size == 1

    def _buffers(self, width: int) -> tuple:
        """Send and receive buffers of ``width`` doubles per row, their counts, displacements.

        Kept for the set's life (the rows are fixed): a step allocates nothing here.
        """
        if width not in self._plans:
            counts = self._counts * width
            self._plans[width] = (np.empty((self.rows.size, width)),
                                  np.empty((self.rows.size, width)),
                                  counts, _displacements(counts))
        return self._plans[width]

    def _send(self, send: np.ndarray, recv: np.ndarray, counts: np.ndarray,
              displ: np.ndarray) -> np.ndarray:
        """Alltoallv of the rows of ``send`` to the ranks sharing them, into ``recv``."""
        self.comm.Alltoallv([send, (counts, displ), MPI.DOUBLE],
                            [recv, (counts, displ), MPI.DOUBLE])
        return recv

    def reduce(self, values: np.ndarray, op: str) -> None:
        """Reduce ``values`` in place with ``op`` = "max" or "min" over the sharing ranks.

        A NaN on any rank holding a node gives NaN there on all of them.

        Args:
            values: (n,) compact values, or (k, n): k arrays reduced together.
            op: "max" or "min".
        """
        if self.serial:
            return
        rows = values if values.ndim == 2 else values[np.newaxis]  # a view: reduced in place
        send, *rest = self._buffers(rows.shape[0])
        _take(rows, self.rows, send)
        _fold(rows, self.rows, self._send(send, *rest), op == "max")

    def cell_sum(self, src: np.ndarray, flat: np.ndarray, out: np.ndarray,
                 also_max: np.ndarray | None = None) -> None:
        """Complete the nodal sums ``out`` on the shared rows (collective).

        Args:
            src: (n, n_slots) slot sources of the rows (:func:`fem_runout.cellsum.sources`).
            flat: (n_cells * 4, bs) this rank's contributions.
            out: (n, bs) the totals of this rank's slots; the shared rows are overwritten with
                the totals over all ranks (every slot from the rank that filled it, totalled
                in the slots' order: the one-rank formula on every rank holding the row).
            also_max: (k, n) values reduced in place (max over the sharing ranks) in the same
                message, as :meth:`reduce` would.
        """
        if self.serial:
            return
        n_slots, bs = src.shape[1], flat.shape[1]
        vals = self._no_values if also_max is None else also_max
        width = n_slots * bs
        send, *rest = self._buffers(width + vals.shape[0])
        _pack(src, flat, self.rows, vals, send)
        recv = self._send(send, *rest)
        acc = self._acc.get(width)
        if acc is None:
            acc = self._acc[width] = np.empty((self._uniq.size, width))
        _unpack(send, recv, self.rows, self._uniq, self._where, bs, acc, out, vals)
