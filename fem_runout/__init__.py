"""fem_runout: depth-averaged run-out of landslides and debris flows with FEniCSx.

Public API (imported lazily so that the command line stays fast)::

    from fem_runout import load_case, run
    case = load_case("cases/inclined_dam_break.yaml", overrides=["time.end=2"])
    result = run(case)          # collective under MPI; arrays on rank 0
"""

from __future__ import annotations

import os
from typing import Any


def _one_thread_per_rank() -> None:
    """Under ``mpirun -n N`` (N > 1) default every thread pool to one thread per rank.

    Set before numpy, numba and DOLFINx load their pools (a user's own setting wins). Without
    it OpenBLAS starts a worker per rank that spins between calls: 3 busy threads for 2 ranks
    on 2 cores, measured with ``top -H`` under ``mpiexec -n 2 python -m fem_runout``.
    """
    sizes = (os.environ.get(k, "") for k in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE",
                                              "MPI_LOCALNRANKS"))
    if any(v.isdigit() and int(v) > 1 for v in sizes):
        for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                    "NUMBA_NUM_THREADS"):
            os.environ.setdefault(key, "1")


_one_thread_per_rank()

# numba's cache checks a kernel's own file only: drop kernels whose imported modules changed
from fem_runout.numba_cache import invalidate_once as _invalidate_once  # noqa: E402

_invalidate_once()

# The DOLFINx wheel finds its MPI library through mpi4py: load it before any submodule
# imports DOLFINx (import sorting may put ``import dolfinx`` first in a module).
from mpi4py import MPI as _MPI  # noqa: E402, F401

__all__ = ["load_case", "run"]


def __getattr__(name: str) -> Any:
    if name == "load_case":
        from fem_runout.config import load_case

        return load_case
    if name == "run":
        from fem_runout.api import run

        return run
    raise AttributeError(name)
