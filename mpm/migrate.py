"""Particle migration between ranks, with the particles balanced over the ranks.

DAMPM's grid sums are exact (:mod:`fem_runout.exact_sum`) and its nodal grid is global
(:mod:`mpm.nodal`), so a particle may live on any rank: the result has the same bits whatever
the split. The split is therefore chosen for speed, not by the mesh partition (a flow covering
a small, moving part of the DEM sat 80 % on one of two ranks when particles followed the owner
of their cell): rank ``r`` holds the particles of a strip of the grid with about ``1/P`` of
the estimated cost (:func:`balanced_destinations`), contiguous so that each rank writes to a compact
range of nodes: a run of cells in row-major order on the grid (whole rows but at its ends),
a strip across the domain on a gmsh mesh. The strips follow the particle counts per strip
unit (``grid.rows``; on a gmsh mesh each particle weighted by its estimated cost; on the grid
each cell holding particles adds ``grid.unit_cost`` for its nodes' work), integers summed over
the ranks, so they are the same on every rank and change only when the flow moves.

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
    """Rank of every particle for strips with equal estimated costs (collective).

    Strip unit ``k`` (``grid.rows``: a cell of the grid, in row-major order; a band of cells
    on a gmsh mesh) of cost ``c_k`` and ``C_k`` the cost of the units before goes to
    rank ``floor(P (C_k + c_k/2) / N)``, ``N`` the total cost: monotone in ``k`` (strips), and
    every rank's cost differs from ``N/P`` by at most about one unit's. The counts are summed
    over the ranks on the units between the first and the last one holding particles (one reduction
    of that range, one of the counts): the flow's rows, not the DEM's. On a gmsh mesh a
    particle counts with its relative cost (``grid.balance_weights``: 3 inside its cell, 6
    across a side, 9 around a vertex, 2 at rest); on the grid each counts 1 and a cell holding
    any adds ``grid.unit_cost`` (:data:`mpm.grid.CELL_COST`): the work of its nodes (the P2G box,
    the nodal update and friction), which is not the same per particle on every strip — a
    deposit's thin margins hold few particles per cell, a moving front many.
    """
    comm = grid.comm
    rows = grid.rows(particles.cell)
    if comm.size == 1:
        return np.zeros(rows.size, dtype=np.int64)
    span = np.array([-rows.min(initial=grid.n_rows), rows.max(initial=-1)], dtype=np.int64)
    comm.Allreduce(MPI.IN_PLACE, span, op=MPI.MAX)
    first, last = -int(span[0]), int(span[1])
    if last < first:  # no particle anywhere
        return np.zeros(rows.size, dtype=np.int64)
    weights = grid.balance_weights(particles)  # integers: the sums are exact on any split
    unit = rows - first
    counts = np.bincount(unit, weights, minlength=last - first + 1).astype(np.int64)
    comm.Allreduce(MPI.IN_PLACE, counts, op=MPI.SUM)
    counts += grid.unit_cost * (counts > 0)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(rows.size, dtype=np.int64)
    below = np.cumsum(counts) - counts
    rank_of_row = np.minimum((2 * below + counts) * comm.size // (2 * total), comm.size - 1)
    return rank_of_row[unit]


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
