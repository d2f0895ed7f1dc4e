"""The numba assembler on 2 and 3 ranks: DOLFINx's bits with ghosts (run under mpiexec)."""

from mpi4py import MPI

from tests.test_assembly import check_subset, check_whole_mesh


def test_whole_mesh_bitwise_parallel() -> None:
    check_whole_mesh(MPI.COMM_WORLD)


def test_subset_entities_parallel() -> None:
    check_subset(MPI.COMM_WORLD)
