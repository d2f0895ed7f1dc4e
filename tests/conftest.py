"""Test configuration: under MPI, a failing rank ends the whole job instead of hanging it."""

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402


@pytest.hookimpl(trylast=True)
def pytest_runtest_logreport(report):
    """Abort every rank as soon as a test fails on one of them (size > 1 only).

    With ``-x`` a rank that stops early would leave the others waiting in a collective.
    """
    comm = MPI.COMM_WORLD
    if comm.size > 1 and report.failed:
        print(f"\n[rank {comm.rank}] {report.nodeid} failed:\n{report.longreprtext}", flush=True)
        comm.Abort(1)
