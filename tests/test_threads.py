"""One thread per rank under ``mpirun``: thread pools default to 1 when MPI starts N > 1 ranks."""

import os
import subprocess
import sys

PROBE = ("import fem_runout, os, numba; "
         "print(os.environ.get('OPENBLAS_NUM_THREADS'), numba.get_num_threads())")


def _probe(**env: str) -> list[str]:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                          "NUMBA_NUM_THREADS", "PMI_SIZE", "OMPI_COMM_WORLD_SIZE",
                          "MPI_LOCALNRANKS")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**clean, **env}, check=True,
                         capture_output=True, text=True)
    return out.stdout.split()


def test_thread_pools_default_to_one_per_rank_under_mpi():
    """An OpenBLAS worker spinning next to each rank made avaKot DAMPM 85 s instead of 20 s."""
    assert _probe(PMI_SIZE="2") == ["1", "1"]  # MPICH / Hydra
    assert _probe(OMPI_COMM_WORLD_SIZE="4") == ["1", "1"]  # Open MPI
    assert _probe(PMI_SIZE="2", OPENBLAS_NUM_THREADS="2", NUMBA_NUM_THREADS="2") == ["2", "2"]
    single = _probe(PMI_SIZE="1")
    assert single[0] == "None"  # one rank: the libraries' own defaults
