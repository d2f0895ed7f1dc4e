"""Particle migration between ranks, with the particles balanced over the ranks.

DAMPM's grid sums are exact (:mod:`fem_runout.exact_sum`) and its nodal grid is global
(:mod:`mpm.nodal`), so a particle may live on any rank: the result has the same bits whatever
the split. The split is therefore chosen for speed, not by the mesh partition (a flow covering
a small, moving part of the DEM sat 80 % on one of two ranks when particles followed the owner
of their cell): rank ``r`` holds the particles of a strip of grid rows with about ``N/P``
particles (:func:`balanced_destinations`), contiguous so that each rank writes to a compact
range of nodes. The strips follow the particle counts per row (on a gmsh mesh, each particle
weighted by its estimated cost), integers summed over the ranks,
so they are the same on every rank and change only when the flow moves.

The solver rebalances every :data:`REBALANCE_EVERY` steps, not every step: in between a
particle stays on its rank wherever it moves (the results do not depend on where particles
live), and a strip's particles drift by at most a few cells, which widens the ranks' P2G
boxes a little. Rebalancing every step copied every particle array on every step.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from mpm.grid import ParticleGrid
from mpm.particles import FLOAT_FIELDS, Particles

__all__ = ["REBALANCE_EVERY", "balanced_destinations", "migrate"]

#: Steps between two rebalancings of the particles over the ranks (speed only: the results
#: have the same bits for any value).
REBALANCE_EVERY = 10

_WIDTH = len(FLOAT_FIELDS) + 2


def balanced_destinations(grid: ParticleGrid, particles: Particles) -> np.ndarray:
    """Rank of every particle for strips of rows with equal particle counts (collective).

    Row ``k`` with ``c_k`` particles and ``C_k`` particles in the rows below goes to rank
    ``floor(P (C_k + c_k/2) / N)``: monotone in ``k`` (strips), and every rank's count differs
    from ``N/P`` by at most about one row's count. One allreduce of ``ny`` integers. On a gmsh
    mesh a particle counts with its relative cost (``grid.balance_weights``: 1 inside its
    cell, 2 across a side, 3 around a vertex); on the grid each counts 1.
    """
    comm = grid.comm
    rows = grid.rows(particles.cell)
    if comm.size == 1:
        return np.zeros(rows.size, dtype=np.int64)
    weights = grid.balance_weights(particles)  # integers: the sums are exact on any split
    counts = np.bincount(rows, weights, minlength=grid.n_rows).astype(np.int64)
    comm.Allreduce(MPI.IN_PLACE, counts, op=MPI.SUM)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(rows.size, dtype=np.int64)
    below = np.cumsum(counts) - counts
    rank_of_row = np.minimum((2 * below + counts) * comm.size // (2 * total), comm.size - 1)
    return rank_of_row[rows]


def migrate(grid: ParticleGrid, particles: Particles,
            dest: np.ndarray | None = None) -> tuple[Particles, int]:
    """Send every particle to its destination rank (collective).

    Particles must lie inside the rectangle (valid ``cell``). The ones that stay keep their
    order; the received ones follow, by source rank.

    Args:
        grid: The particle grid (cell → owner table).
        particles: The particles of this rank after the position update.
        dest: Destination rank of each particle; default: the rank owning its cell.

    Returns:
        The particles now on this rank, and the number this rank sent.
    """
    comm = grid.comm
    if comm.size == 1:
        return particles, 0
    if dest is None:
        dest = grid.owner[particles.cell]
    leaving = np.flatnonzero(dest != comm.rank)
    order = leaving[np.argsort(dest[leaving], kind="stable")]
    send_counts = np.bincount(dest[leaving], minlength=comm.size).astype(np.int64)
    recv_counts = np.empty_like(send_counts)
    comm.Alltoall(send_counts, recv_counts)
    send = np.ascontiguousarray(particles.select(order).pack()).reshape(-1)
    recv = np.empty(int(recv_counts.sum()) * _WIDTH)
    sc, rc = send_counts * _WIDTH, recv_counts * _WIDTH
    sd = np.concatenate([[0], np.cumsum(sc)[:-1]])
    rd = np.concatenate([[0], np.cumsum(rc)[:-1]])
    comm.Alltoallv([send, (sc, sd)], [recv, (rc, rd)])
    if leaving.size == 0 and recv.size == 0:
        return particles, 0
    stay = np.ones(len(particles), dtype=bool)
    stay[leaving] = False
    came = Particles.unpack(recv, particles.has_affine, particles.has_quad)
    merged = particles.select_and_append(stay, came)
    return merged, int(leaving.size)
