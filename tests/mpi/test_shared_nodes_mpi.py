"""Exchanges on the active set's shared nodes only (issue 16): the whole mesh's results.

The mesh is cut into stripes four cells wide dealt to the ranks in turn, so a flow region
crosses several cuts; the compact sums and extrema must equal the whole-vector exchanges on
the same partition and the one-rank sums bit for bit.
"""

import numpy as np
from mpi4py import MPI

from fem_runout.active import ActiveSet
from fem_runout.mesh import GhostReducer, build_discretization
from fem_runout.partition import cell_partitioner

WORLD = MPI.COMM_WORLD
NX, NY = 24, 16
EXTENT = (0.0, 24.0, 0.0, 16.0)


def _disc(comm):
    owners = (np.tile(np.arange(NX), NY) // 4 % comm.size).astype(np.int32)
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


def test_compact_sums_equal_the_whole_vector_sums_and_one_rank():
    disc = _disc(WORLD)
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
    assert WORLD.allreduce(a.reducer.ghost_rows.size, op=MPI.SUM) > 0 or WORLD.size == 1


def test_compact_extrema_equal_the_whole_vector_extrema():
    disc = _disc(WORLD)
    a = _active(disc)
    rng = np.random.default_rng(11 + WORLD.rank)  # each rank its own values at shared nodes
    values = rng.normal(size=(2, a.nodes.size))
    whole = np.full((2, disc.coords.shape[0]), -np.inf)
    whole[:, a.nodes] = values
    GhostReducer(disc).reduce(whole, "max")
    compact = values.copy()
    a.reducer.reduce(compact, "max")
    assert np.array_equal(compact, whole[:, a.nodes])
    whole[:, :] = np.inf
    whole[:, a.nodes] = values
    GhostReducer(disc).reduce(whole, "min")
    a.reducer.reduce(values, "min")
    assert np.array_equal(values, whole[:, a.nodes])
