"""Exchanges on the active set's shared nodes only (issue 16): the whole mesh's results.

The mesh is cut into stripes four cells wide dealt to the ranks in turn, so a flow region
crosses several cuts, or into blocks of 4 x 4 cells dealt so that three ranks meet at the
blocks' corners (on 3 ranks): nodes that two ranks hold as ghosts of a third. The compact
sums and extrema must equal the one-rank sums bit for bit and the extrema over the ranks
(gathered by coordinates), on every rank holding a node.
"""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.active import ActiveSet
from fem_runout.mesh import GhostReducer, build_discretization
from fem_runout.partition import cell_partitioner

WORLD = MPI.COMM_WORLD
NX, NY = 24, 16
EXTENT = (0.0, 24.0, 0.0, 16.0)


PATTERNS = ("stripes", "blocks")


def _disc(comm, pattern="stripes"):
    i, j = np.tile(np.arange(NX), NY), np.repeat(np.arange(NY), NX)
    block = i // 4 if pattern == "stripes" else i // 4 + 2 * (j // 4)
    owners = (block % comm.size).astype(np.int32)
    part = cell_partitioner(owners, NX) if comm.size > 1 else None
    return build_discretization(comm, EXTENT, (NX, NY), {}, part)


def _active(disc):
    """The set around the nodes within 5 m of (12.3, 7.7): it straddles the stripes' cuts."""
    a = ActiveSet(disc, GhostReducer(disc))
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    a.rebuild(((x - 12.3) ** 2 + (y - 7.7) ** 2 < 25.0).astype(float))
    return a


def _contributions(disc, cells):
    """Three values per cell node from the cell's centre and the node's corner (any partition)."""
    centre = disc.coords[disc.cell_nodes[cells]].mean(axis=1)
    corner = disc.slot[cells]
    c = np.arange(3)
    return np.sin(3.1 * centre[:, None, None, 0] + 1.7 * corner[:, :, None] + c) * \
        np.exp(0.37 * centre[:, None, None, 1]) * 10.0 ** (-3 * c)


def _by_coordinates(disc, nodes, values):
    return {(round(float(x), 6), round(float(y), 6)): tuple(v)
            for (x, y), v in zip(disc.coords[nodes, :2], values, strict=True)}


@pytest.mark.parametrize("pattern", PATTERNS)
def test_compact_sums_equal_the_whole_vector_sums_and_one_rank(pattern):
    disc = _disc(WORLD, pattern)
    a = _active(disc)
    got = a.cell_sum(_contributions(disc, a.owned))
    full = np.zeros((disc.n_owned_cells, 4, 3))
    full[a.owned] = _contributions(disc, a.owned)
    assert np.array_equal(got, disc.cell_sum(full)[a.nodes])
    serial = _disc(MPI.COMM_SELF)
    s = _active(serial)
    reference = _by_coordinates(serial, s.nodes, s.cell_sum(_contributions(serial, s.owned)))
    mine = _by_coordinates(disc, a.nodes, got)
    assert set(mine) <= set(reference)
    assert all(mine[k] == reference[k] for k in mine)
    assert WORLD.allreduce(a.reducer.rows.size, op=MPI.SUM) > 0 or WORLD.size == 1
    held = {}
    for part in WORLD.allgather(list(mine)):
        for k in part:
            held[k] = held.get(k, 0) + 1
    assert max(held.values()) >= (min(WORLD.size, 3) if pattern == "blocks" else 1)


def _extrema_over_ranks(disc, nodes, values, op):
    """Max (min) over every rank's values at each coordinate, gathered: the reference."""
    mine = [(k, tuple(v)) for k, v in _by_coordinates(disc, nodes, values.T).items()]
    best = {}
    for k, v in (item for part in WORLD.allgather(mine) for item in part):
        best[k] = v if k not in best else tuple(op(a, b) for a, b in zip(best[k], v,
                                                                          strict=True))
    return best


@pytest.mark.parametrize("pattern", PATTERNS)
def test_compact_extrema_equal_the_extrema_over_the_ranks(pattern):
    disc = _disc(WORLD, pattern)
    a = _active(disc)
    rng = np.random.default_rng(11 + WORLD.rank)  # each rank its own values at shared nodes
    values = rng.normal(size=(2, a.nodes.size))
    whole = np.full((2, disc.coords.shape[0]), -np.inf)
    whole[:, a.nodes] = values
    GhostReducer(disc).reduce(whole, "max")
    compact = values.copy()
    a.reducer.reduce(compact, "max")
    assert np.array_equal(compact, whole[:, a.nodes])
    reference = _extrema_over_ranks(disc, a.nodes, values, max)
    assert _by_coordinates(disc, a.nodes, compact.T) == \
        {k: reference[k] for k in _by_coordinates(disc, a.nodes, compact.T)}
    whole[:, :] = np.inf
    whole[:, a.nodes] = values
    GhostReducer(disc).reduce(whole, "min")
    reference = _extrema_over_ranks(disc, a.nodes, values, min)
    a.reducer.reduce(values, "min")
    assert np.array_equal(values, whole[:, a.nodes])
    got = _by_coordinates(disc, a.nodes, values.T)
    assert got == {k: reference[k] for k in got}


def test_a_nan_on_any_rank_holding_a_node_reaches_all_of_them():
    disc = _disc(WORLD, "blocks")
    a = _active(disc)
    x, y = disc.coords[a.nodes, 0], disc.coords[a.nodes, 1]
    at = np.flatnonzero((np.abs(x - 12.0) < 1e-9) & (np.abs(y - 8.0) < 1e-9))  # a block corner
    values = np.full((1, a.nodes.size), float(WORLD.rank))
    if WORLD.rank == WORLD.size - 1:
        values[0, at] = np.nan
    a.reducer.reduce(values, "max")
    assert np.isnan(values[0, at]).all()
    assert np.all(values[0, np.isfinite(values[0])] <= WORLD.size - 1)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_the_exchanges_kept_buffers_give_each_call_its_own_sums(pattern):
    """Calls of several widths, with and without extrema, interleaved on one set (its send,
    receive and slot buffers are kept from call to call): each the bits of a first call."""
    disc = _disc(WORLD, pattern)
    c = _contributions(disc, _active(disc).owned)
    rng = np.random.default_rng(5 + WORLD.rank)
    widths = (3, 1, 2, 3, 1)
    extrema = [rng.normal(size=(2, _active(disc).nodes.size)) for _ in widths]

    def call(a, k):
        contrib = c[:, :, :widths[k]] * (1.0 + k)
        if k % 2 == 0:
            return [a.cell_sum(contrib)]
        vals = extrema[k].copy()
        return [a.cell_sum(contrib, also_max=vals), vals]

    one = _active(disc)
    kept = [x for k in range(len(widths)) for x in call(one, k)]
    fresh = [x for k in range(len(widths)) for x in call(_active(disc), k)]  # a set per call
    assert len(kept) == len(fresh) == 7
    assert all(np.array_equal(x, y) for x, y in zip(kept, fresh, strict=True))
    assert not np.array_equal(kept[0][:, :1], kept[1][:, None])  # the calls differ
