"""A DAMPM step's messages: the split's ids ride with the P2G bounds, the MUSL bound is known.

The same checks run on 2 and 3 ranks in ``tests/mpi/test_mpm_mpi.py``.
"""

import numpy as np
from mpi4py import MPI

from fem_runout.mesh import build_discretization
from mpm.grid import ParticleGrid
from mpm.particles import seed_particles
from mpm.split import DomainSplitter
from tests.mpm_messages import count_messages, momentum_sums_both_ways

COMM = MPI.COMM_WORLD


def test_a_step_sends_one_gather_and_its_sums():
    counting, solver = count_messages(COMM, steps=3)
    sums = 3 if COMM.size > 1 else 0  # the touched nodes' mask, the P2G and the MUSL sums
    # per step: the split's ids with the P2G bounds; the sums; the health check
    assert counting.calls == {"allgather": 3, "Allreduce": 3 * (sums + 1)}
    assert solver.splitter.count > 0  # the pile spreads: its particles did split


def test_the_known_musl_bound_gives_the_sums_of_the_reduced_bound():
    _, solver = count_messages(COMM, steps=1)
    quick, full = momentum_sums_both_ways(solver)
    scale = np.abs(full).max()
    assert scale > 0.0 and np.abs(quick - full).max(initial=0.0) <= 1e-14 * scale


def test_a_split_pair_settled_later_gives_the_ids_of_the_split():
    """The solver sends a pair's ids with the P2G bounds (``split_pair`` now, ``settle`` with
    the next message): the particles and ids are those of ``split``."""
    disc = build_discretization(MPI.COMM_SELF, (100.0, 112.0, -3.0, 4.0), (6, 7), {})
    grid = ParticleGrid(disc)
    one = np.ones(grid.disc.coords.shape[0])
    base = seed_particles(grid, one, 0 * one, 0 * one, 2)
    x0, y0 = base.positions(grid)
    middle = np.flatnonzero((np.abs(x0 - 106.0) < 2.0) & (np.abs(y0 - 0.5) < 2.0))
    base.lx[middle[:3]] *= 4.5  # split twice along x: a second pair
    base.ly[middle[2:6]] *= 2.2
    first = int(base.id.max()) + 1
    a, b = DomainSplitter(grid, 2, first), DomainSplitter(grid, 2, first)
    want = a.split(base.copy())
    got, pending = b.split_pair(base.copy())
    assert b.settle(got, pending, [pending.payload])  # still too wide: split again
    got = b.split(got)
    assert np.array_equal(got.pack(), want.pack())
    assert (b.next_id, b.count) == (a.next_id, a.count) == (first + 16, 16)  # 3 + 3 + 7 + 3
