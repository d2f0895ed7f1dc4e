"""A DAMPM step's messages: the split's ids ride with the P2G bounds, the MUSL bound is known.

The same checks run on 2 and 3 ranks in ``tests/mpi/test_mpm_mpi.py``.
"""

import numpy as np
from mpi4py import MPI

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
