"""The sum over the ranks of DAMPM's particle-to-grid folds, on the nodes some rank touched.

Each rank scatters its particles into a box of nodes around them (:func:`mpm.kernels.p2g`,
rows ``j0 .. j0 + h``, columns ``i0 .. i0 + w``). Only the nodes that some rank touched carry a
sum, a few thousand on avaKot against 3e4 in the rows the flow spans: the ranks mark their
touched nodes in a bit mask of the union of their boxes, and the folds are added over the
marked nodes (one reduction of the mask, one of the union's folds). The folds' sums are exact
(:mod:`fem_runout.exact_sum`), so the result has the same bits on any number of ranks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from mpi4py import MPI

from fem_runout.exact_sum import finite_bounds

__all__ = ["Box", "FoldExchange", "p2g_bounds", "p2g_bounds_of"]


@dataclass(frozen=True)
class Box:
    """Nodes ``j0 <= j < j0 + h``, ``i0 <= i < i0 + w`` of the structured grid (row-major).

    Attributes:
        j0, i0: First row and column.
        h, w: Rows and columns (0 for an empty box).
        nx1: Nodes per grid row.
    """

    j0: int
    i0: int
    h: int
    w: int
    nx1: int

    def nodes(self, local: np.ndarray) -> np.ndarray:
        """Global structured indices of box positions."""
        return (self.j0 + local // max(self.w, 1)) * self.nx1 + self.i0 + local % max(self.w, 1)


@numba.njit(cache=True)
def _touched(flat):
    """Rows with a non-zero entry."""
    out = np.zeros(flat.shape[0], dtype=np.bool_)
    for r in range(flat.shape[0]):
        for c in range(flat.shape[1]):
            if flat[r, c] != 0.0:
                out[r] = True
                break
    return out


class FoldExchange:
    """Add per-rank fold arrays of one box per rank over the ranks, on the touched nodes.

    Built from the first transfer of a step (:meth:`start`); further transfers of the same
    particles (:meth:`sum`) reuse its node list.

    Args:
        comm: The communicator.
    """

    def __init__(self, comm: MPI.Comm) -> None:
        self.comm = comm
        self.nodes = np.zeros(0, dtype=np.int64)
        self._take = np.zeros(0, dtype=np.int64)  # box positions of this rank's touched nodes
        self._put = np.zeros(0, dtype=np.int64)  # their positions in :attr:`nodes`

    def start(self, folds: np.ndarray, box: Box, union: Box,
              also_sum: np.ndarray | None = None) -> np.ndarray:
        """Exact sums (n_union, k) of the nodes any rank touched (collective).

        Args:
            folds: (box nodes, k, 2) this rank's folds (:func:`mpm.kernels.p2g`).
            box: The box of the folds.
            union: The smallest box holding every rank's box (:func:`p2g_bounds`): the ranks
                mark their touched nodes in one bit mask of it (one reduction).
            also_sum: Values summed over the ranks in the same message (in place).
        """
        flat = folds.reshape(len(folds), int(np.prod(folds.shape[1:])))  # (also with none)
        self._take = np.flatnonzero(_touched(flat))
        mine = box.nodes(self._take)
        if self.comm.size == 1:
            self.nodes, self._put = mine, np.arange(mine.size)
        else:
            pos = (mine // union.nx1 - union.j0) * union.w + mine % union.nx1 - union.i0
            size = union.h * union.w
            bits = np.zeros(size, dtype=np.bool_)
            bits[pos] = True
            packed = np.packbits(bits)
            self.comm.Allreduce(MPI.IN_PLACE, packed, op=MPI.BOR)
            touched = np.flatnonzero(np.unpackbits(packed, count=size))
            self.nodes = union.nodes(touched)  # increasing: the box is row-major
            self._put = np.searchsorted(touched, pos)
        return self.sum(folds, also_sum)

    def sum(self, folds: np.ndarray, also_sum: np.ndarray | None = None) -> np.ndarray:
        """Exact sums on :attr:`nodes` of folds of the box of :meth:`start` (collective).

        ``also_sum`` (floats) is summed over the ranks in the same message (in place).
        """
        width = int(np.prod(folds.shape[1:]))
        extra = 0 if also_sum is None else also_sum.size
        buf = np.zeros(self.nodes.size * width + extra)
        out = buf[:self.nodes.size * width].reshape(self.nodes.size, *folds.shape[1:])
        out[self._put] = folds[self._take]
        if self.comm.size > 1:
            if extra:
                buf[-extra:] = also_sum.ravel()
            self.comm.Allreduce(MPI.IN_PLACE, buf, op=MPI.SUM)
            if extra:
                also_sum[...] = buf[-extra:].reshape(also_sum.shape)
        return out[..., 0] + out[..., 1]

def p2g_bounds(local: np.ndarray, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
    """Global bounds of any P2G contribution per column, and the ranks' boxes' union.

    Collective: one max reduction. Weights are <= 1 and gradients <= max |dN|. Every single
    quantity is maximised over the ranks before the maxima are combined: a max over ranks of
    per-rank sums of maxima would depend on which rank holds which particle, and so would the
    exact sums' folds.

    Args:
        local: This rank's maxima and box from :func:`mpm.forces.transfer_bounds` (15).
        comm: Communicator.

    Returns:
        ``(bounds, union)``: the (7,) bounds of ``m, m u, m v``, the two force columns, ``A``
        and ``V``; and ``-min row, max row, -min column, max column`` of all ranks' nodes
        (``-inf`` with no particle anywhere), for :meth:`mpm.nodal.NodalGrid.box`.
    """
    glob = _finite(local)
    comm.Allreduce(MPI.IN_PLACE, glob, op=MPI.MAX)
    return _combine(glob)


def p2g_bounds_of(every: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`p2g_bounds` from every rank's ``local`` (gathered with another message; no MPI)."""
    return _combine(np.max([_finite(local) for local in every], axis=0))


def _finite(local: np.ndarray) -> np.ndarray:
    """Return the maxima with NaN, inf as the largest floats; the box (-inf: none) as it is."""
    glob = finite_bounds(local[:15])
    glob[11:] = local[11:15]
    return glob


def _combine(glob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(bounds, union)`` of :func:`p2g_bounds` from the maxima over the ranks."""
    m, mu, mv, bx, by, sxx, syy, sxy, grad, area, volume = glob[:11]
    return (np.array([m, mu, mv, bx + (sxx + sxy) * grad, by + (sxy + syy) * grad, area, volume]),
            glob[11:])
