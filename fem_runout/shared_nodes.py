"""Exchanges on the shared nodes of a node subset: a step's messages follow the flow (issue 16).

The active set (:mod:`fem_runout.active`) holds a few percent of the mesh's nodes, and so of
the nodes that ranks share. DOLFINx's scatters and a :class:`~fem_runout.mesh.GhostReducer`
move every ghost of the whole vectors, so their cost grows with the partition's cut, not with
the flow: a partition into stripes that balances a moving flow (:mod:`fem_runout.partition`)
multiplied the ghosts and made every exchange dearer. :class:`SharedRows` exchanges only the
set's shared nodes, in compact arrays (row ``k`` is the set's node ``nodes[k]``), with one
``Alltoallv`` each way:

- :meth:`SharedRows.reduce`: max or min over the ranks sharing a node (exact);
- :meth:`SharedRows.cell_sum`: the nodal sums of cell contributions with the slots of
  :mod:`fem_runout.cellsum` (each slot filled by one cell over all ranks, so adding the ranks'
  slots is exact and the total, in a fixed order, is the same bits on any partition).

Every rank sharing a node must agree that it is in the set (the active set's hops are reduced
over the ranks, so they do); then the two ends list the same nodes in the same order.
"""

from __future__ import annotations

import numba
import numpy as np
from mpi4py import MPI

__all__ = ["SharedRows"]


@numba.njit(cache=True)
def _take(values, rows, out):
    """``out[m, r] = values[r, rows[m]]``."""
    for m in range(rows.size):
        for r in range(values.shape[0]):
            out[m, r] = values[r, rows[m]]


@numba.njit(cache=True)
def _fold(values, rows, recv, is_max):
    """``values[r, rows[m]] = max (or min) of itself and recv[m, r]``."""
    for m in range(rows.size):
        i = rows[m]
        for r in range(values.shape[0]):
            v = recv[m, r]
            if (v > values[r, i]) if is_max else (v < values[r, i]):
                values[r, i] = v


@numba.njit(cache=True)
def _put(values, rows, recv):
    """``values[r, rows[m]] = recv[m, r]``."""
    for m in range(rows.size):
        for r in range(values.shape[0]):
            values[r, rows[m]] = recv[m, r]


@numba.njit(cache=True)
def _pack_slots(src, flat, rows, send):
    """``send[m, s, c] = flat[src[rows[m], s], c]`` (0 where the slot is empty)."""
    for m in range(rows.size):
        for s in range(src.shape[1]):
            j = src[rows[m], s]
            for c in range(flat.shape[1]):
                send[m, s, c] = flat[j, c] if j >= 0 else 0.0


@numba.njit(cache=True)
def _fold_slots(src, flat, uniq, where, recv, acc, out):
    """Owned shared rows: own slots plus the received ones, totalled in the slots' order.

    ``acc[u]`` takes the slots of row ``uniq[u]``, ``recv[m]`` is added to ``acc[where[m]]``
    (each slot is non-zero on one rank only: exact), and ``out[uniq[u], c] = ((0 + b_0) +
    b_1) + ...`` as :func:`fem_runout.cellsum.gather_total` sums on one rank.
    """
    _pack_slots(src, flat, uniq, acc)
    for m in range(where.size):
        u = where[m]
        for s in range(acc.shape[1]):
            for c in range(acc.shape[2]):
                acc[u, s, c] += recv[m, s, c]
    for u in range(uniq.size):
        for c in range(acc.shape[2]):
            total = 0.0
            for s in range(acc.shape[1]):
                total = total + acc[u, s, c]
            out[uniq[u], c] = total


@numba.njit(cache=True)
def _put_rows(out, rows, recv):
    """``out[rows[m]] = recv[m]``."""
    for m in range(rows.size):
        for c in range(out.shape[1]):
            out[rows[m], c] = recv[m, c]


def _displacements(counts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


class SharedRows:
    """Exchanges over the shared nodes of a set of local nodes (compact arrays).

    Args:
        comm: The mesh's communicator.
        ghost_rows: Compact rows of the set's ghost nodes, grouped by owner rank.
        ghost_counts: (size,) how many of them each rank owns.
        owned_rows: Compact rows of the set's owned nodes that other ranks hold as ghosts,
            grouped by those ranks (a node appears once per rank holding it).
        owned_counts: (size,) how many rows each rank holds as ghosts.
    """

    def __init__(self, comm: MPI.Comm, ghost_rows: np.ndarray, ghost_counts: np.ndarray,
                 owned_rows: np.ndarray, owned_counts: np.ndarray) -> None:
        self.comm = comm
        self.ghost_rows = np.ascontiguousarray(ghost_rows, dtype=np.int64)
        self.owned_rows = np.ascontiguousarray(owned_rows, dtype=np.int64)
        self._counts = (np.asarray(ghost_counts, np.int64), np.asarray(owned_counts, np.int64))
        self._uniq, self._where = np.unique(self.owned_rows, return_inverse=True)
        self._plans: dict[tuple[bool, int], tuple] = {}

    @property
    def serial(self) -> bool:
        """True on one rank (nothing to exchange)."""
        return self.comm.size == 1

    def _send(self, data: np.ndarray, to_owners: bool) -> np.ndarray:
        """Alltoallv of rows of ``data`` to the owners (or back to the ghosts)."""
        width = int(np.prod(data.shape[1:], dtype=np.int64))
        key = (to_owners, width)
        if key not in self._plans:
            out, into = self._counts if to_owners else self._counts[::-1]
            self._plans[key] = (out * width, _displacements(out * width),
                                into * width, _displacements(into * width), int(into.sum()))
        out, sd, into, rd, n = self._plans[key]
        recv = np.empty((n,) + data.shape[1:])
        self.comm.Alltoallv([np.ascontiguousarray(data), (out, sd), MPI.DOUBLE],
                            [recv, (into, rd), MPI.DOUBLE])
        return recv

    def reduce(self, values: np.ndarray, op: str) -> None:
        """Reduce ``values`` in place with ``op`` = "max" or "min" over the sharing ranks.

        Args:
            values: (n,) compact values, or (k, n): k arrays reduced together.
            op: "max" or "min".
        """
        if self.serial:
            return
        rows = values if values.ndim == 2 else values[np.newaxis]  # a view: reduced in place
        send = np.empty((self.ghost_rows.size, rows.shape[0]))
        _take(rows, self.ghost_rows, send)
        _fold(rows, self.owned_rows, self._send(send, True), op == "max")
        back = np.empty((self.owned_rows.size, rows.shape[0]))
        _take(rows, self.owned_rows, back)
        _put(rows, self.ghost_rows, self._send(back, False))

    def cell_sum(self, src: np.ndarray, flat: np.ndarray, out: np.ndarray,
                 also_max: np.ndarray | None = None) -> None:
        """Complete the nodal sums ``out`` on the shared rows (collective).

        Args:
            src: (n, n_slots) slot sources of the rows (:func:`fem_runout.cellsum.sources`).
            flat: (n_cells * 4, bs) this rank's contributions.
            out: (n, bs) the totals of this rank's slots; the shared rows are overwritten with
                the totals over all ranks (the owners' sums, sent back to the ghosts).
            also_max: (k, n) values reduced in place (max over the sharing ranks) in the same
                messages, as :meth:`reduce` would.
        """
        if self.serial:
            return
        n_slots, bs = src.shape[1], flat.shape[1]
        vals = np.empty((0, out.shape[0])) if also_max is None else also_max
        k, width = vals.shape[0], n_slots * bs
        send = np.empty((self.ghost_rows.size, width + k))
        _pack_slots(src, flat, self.ghost_rows, send[:, :width].reshape(-1, n_slots, bs))
        _take(vals, self.ghost_rows, send[:, width:])
        recv = self._send(send, True)
        acc = np.empty((self._uniq.size, n_slots, bs))
        _fold_slots(src, flat, self._uniq, self._where, recv[:, :width].reshape(-1, n_slots, bs),
                    acc, out)
        _fold(vals, self.owned_rows, recv[:, width:], True)
        back = np.empty((self.owned_rows.size, bs + k))
        back[:, :bs] = out[self.owned_rows]
        _take(vals, self.owned_rows, back[:, bs:])
        got = self._send(back, False)
        _put_rows(out, self.ghost_rows, got[:, :bs])
        _put(vals, self.ghost_rows, got[:, bs:])
