"""TG2-PC's cell kernels against the UFL forms on 2 and 3 ranks (run under mpiexec)."""

from mpi4py import MPI

from tests.test_cell_kernels import check_cell_by_cell_corrector, check_cell_by_cell_predictor


def test_cell_by_cell_corrector_parallel() -> None:
    check_cell_by_cell_corrector(MPI.COMM_WORLD)


def test_cell_by_cell_predictor_parallel() -> None:
    check_cell_by_cell_predictor(MPI.COMM_WORLD)
    check_cell_by_cell_predictor(MPI.COMM_WORLD, distort=1.5)
