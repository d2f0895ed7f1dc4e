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

from fem_runout.exact_sum import exact_total, fold_extractors
from mpm.exchange import FoldExchange, p2g_bounds
from mpm.forces import transfer_bounds
from mpm.kernels import p2g_momentum
from mpm.nodal import NodalGrid

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
        return p2g_bounds(transfer_bounds((i0[k], j0[k], wx[k], dwx[k], wx[k], dwx[k], n, 1, 1.0,
                                           1.0), mass[k], u[k], v[k],
                                          np.ascontiguousarray(forces[:, k]), area[k],
                                          volume[k]), comm)[0]

    whole = bounds(np.arange(n), MPI.COMM_SELF)
    assert np.array_equal(bounds(_share(n), WORLD), whole)
    assert whole[3] == 50.0 + 70.0 * 0.5  # body and stress (x |dN|) add up, whoever holds them


def test_fold_exchange_sums_the_touched_nodes_with_the_bits_of_one_rank():
    rng = np.random.default_rng(8)
    n, nx, ny = 3000, 30, 20
    i0, j0 = rng.integers(0, nx, size=n), rng.integers(0, ny, size=n)
    j0[: n // 2] = rng.integers(0, 4, size=n // 2)  # two clusters: a box holding both is
    j0[n // 2:], i0[n // 2:] = rng.integers(14, 17, size=n - n // 2), rng.integers(  # mostly
        20, 26, size=n - n // 2)  # empty
    wx, wy = rng.uniform(0.0, 1.0, size=(n, 3)), rng.uniform(0.0, 1.0, size=(n, 3))
    wy[:, 2] = 0.0
    mass, u, v = 10.0 ** rng.uniform(-8, 0, size=n), rng.normal(size=n), rng.normal(size=n)
    ext = fold_extractors([np.abs(mass * u).max(), np.abs(mass * v).max()], n)

    def run(k, comm):
        nodal = NodalGrid.__new__(NodalGrid)
        nodal.row_length = nx + 1
        bounds = [-j0[k].min(), np.minimum(j0[k] + 2, ny).max(), -i0[k].min(),
                  np.minimum(i0[k] + 2, nx).max()] if k.size else [-np.inf] * 4
        box = nodal.box(np.array(bounds, dtype=float))
        folds = p2g_momentum((i0[k], j0[k], wx[k], 0 * wx[k], wy[k], 0 * wy[k], nx, ny, 1.0,
                              1.0), mass[k], u[k], v[k], np.zeros((4, k.size)),
                             np.array([box.j0, box.i0, box.h, box.w]), ext)
        union = nodal.box(np.array([-j0.min(), np.minimum(j0 + 2, ny).max(), -i0.min(),
                                    np.minimum(i0 + 2, nx).max()], dtype=float))
        exchange = FoldExchange(comm)
        sums = exchange.start(folds, box, union)
        return exchange.nodes, sums

    nodes, sums = run(np.arange(n), MPI.COMM_SELF)
    part_nodes, part_sums = run(_share(n), WORLD)
    assert np.array_equal(part_nodes, nodes) and np.array_equal(part_sums, sums)
    assert nodes.size < (nx + 1) * (ny + 1)  # only the touched nodes are exchanged


def test_reported_volumes_have_the_same_bits_on_any_split():
    """The summary's released and deposit volumes (``exact_global_sum``) do not depend on
    which rank holds which node (a plain sum over the ranks differed in the last bits)."""
    from fem_runout.output.gather import exact_global_sum

    rng = np.random.default_rng(12)
    terms = rng.uniform(0.0, 100.0, 20_000) * 10.0 ** rng.uniform(-9, 0, 20_000)
    whole = exact_global_sum(MPI.COMM_SELF, terms)
    assert exact_global_sum(WORLD, terms[_share(terms.size)]) == whole
    assert abs(whole - math.fsum(terms)) <= 1e-15 * math.fsum(terms)
