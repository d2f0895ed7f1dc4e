"""Exact sums split over the ranks (issue 16): the same bits as on one rank.

Each rank takes a different share of the same global data; the results must equal the
one-rank values bitwise. DAMPM's fold extractors must come from bounds that do not depend on
the split: a rank holding the largest body force and another the largest stress used to give
a different extractor than one rank holding both (avaKot: 1 and 2 ranks differed after 18
steps, and ended one step and 22 particles apart).
"""

import math

import numpy as np
from mpi4py import MPI

from fem_runout.exact_sum import exact_total
from mpm.forces import transfer_bounds
from mpm.solver import p2g_bounds

WORLD = MPI.COMM_WORLD


def _share(n: int) -> np.ndarray:
    """This rank's indices of ``n`` items: rank r takes every item with ``k % size == r``."""
    return np.arange(WORLD.rank, n, WORLD.size)


def test_exact_total_same_bits_on_any_split():
    rng = np.random.default_rng(5)
    values = 10.0 ** rng.uniform(-12, 3, size=10_000) * rng.choice([-1.0, 1.0], size=10_000)
    bound = float(np.abs(values).max())
    whole = exact_total(values, bound, values.size, MPI.COMM_SELF)
    split = exact_total(values[_share(values.size)], bound, values.size, WORLD)
    assert split == whole
    assert abs(whole - math.fsum(values)) <= 1e-15 * np.abs(values).sum()


def test_p2g_bounds_do_not_depend_on_which_rank_holds_the_maxima():
    n = 12
    rng = np.random.default_rng(3)
    mass, u, v, area, volume = (rng.uniform(0.1, 1.0, n) for _ in range(5))
    forces = np.zeros((5, n))
    forces[0, 0] = 50.0  # the largest body force on one particle ...
    forces[2, 1] = 70.0  # ... the largest stress on the next one (another rank when split)
    i0, j0 = np.arange(n), np.zeros(n, dtype=np.int64)  # one row of 12 cells
    wx, dwx = np.full((n, 3), 0.5), np.ones((n, 3))

    def bounds(k, comm):
        return p2g_bounds(transfer_bounds(i0[k], j0[k], wx[k], dwx[k], wx[k], dwx[k], n, 1, 1.0,
                                          1.0, mass[k], u[k], v[k],
                                          np.ascontiguousarray(forces[:, k]), area[k],
                                          volume[k]), comm)

    whole, window = bounds(np.arange(n), MPI.COMM_SELF)
    part, part_window = bounds(_share(n), WORLD)
    assert np.array_equal(part, whole) and part_window == window == (0, 2 * (n + 1))
    assert whole[3] == 50.0 + 70.0 * 0.5  # body and stress (x |dN|) add up, whoever holds them
