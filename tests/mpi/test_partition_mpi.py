"""The path partition under MPI (issue 16): the mesh follows the owners, results do not."""

import numpy as np
from mpi4py import MPI

from fem_runout.mesh import build_discretization
from fem_runout.partition import cell_partitioner

WORLD = MPI.COMM_WORLD


def test_mesh_cells_go_to_the_ranks_the_owners_name():
    nx, ny = 24, 10
    owners = ((np.arange(nx * ny) % nx) // 4 % WORLD.size).astype(np.int32)  # stripes of 4
    disc = build_discretization(WORLD, (0.0, 24.0, 0.0, 10.0), (nx, ny), {},
                                cell_partitioner(owners, nx))
    centre = disc.coords[disc.cell_nodes].mean(axis=1)
    index = np.floor(centre[:, 1]).astype(int) * nx + np.floor(centre[:, 0]).astype(int)
    n_own = disc.n_owned_cells
    assert np.all(owners[index[:n_own]] == WORLD.rank)
    assert WORLD.allreduce(n_own) == nx * ny
    if WORLD.size > 1:  # ghosts: the cells across each stripe edge, owned elsewhere
        ghosts = index[n_own:]
        assert ghosts.size > 0 and np.all(owners[ghosts] != WORLD.rank)
