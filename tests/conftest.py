"""Test configuration: under MPI, a failing rank ends the whole job instead of hanging it, and
ranks that finish a test early wait for the others asleep."""

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
if "FEM_RUNOUT_CACHE" not in os.environ:  # the tests' outline meshes: not in the user's cache
    import atexit
    import shutil
    import tempfile

    os.environ["FEM_RUNOUT_CACHE"] = tempfile.mkdtemp(prefix="fem_runout_test_cache_")
    atexit.register(shutil.rmtree, os.environ["FEM_RUNOUT_CACHE"], ignore_errors=True)

import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402

from tests.idle import idle_barrier  # noqa: E402


@pytest.hookimpl(trylast=True)
def pytest_runtest_logreport(report):
    """Abort every rank as soon as a test fails on one of them (size > 1 only).

    With ``-x`` a rank that stops early would leave the others waiting in a collective.
    """
    comm = MPI.COMM_WORLD
    if comm.size > 1 and report.failed:
        print(f"\n[rank {comm.rank}] {report.nodeid} failed:\n{report.longreprtext}", flush=True)
        comm.Abort(1)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    """After a test that passed on this rank, wait for the other ranks without spinning.

    Many MPI tests end with a serial reference run on rank 0 (``COMM_SELF``). Without this the
    other ranks would wait for it inside the next test's first collective, spinning beside it
    (:func:`tests.idle.idle_barrier`). A rank whose test failed does not wait: its report
    aborts the job (:func:`pytest_runtest_logreport`). A test that raised but is not reported
    as failed (skipped in its body, or an expected failure of an ``xfail`` mark, as the hard
    cases' known failures) waits like a passed one, so the ranks stay in step.
    """
    comm = MPI.COMM_WORLD
    try:
        result = yield
    except BaseException as exc:
        if comm.size > 1 and (isinstance(exc, pytest.skip.Exception)
                              or item.get_closest_marker("xfail") is not None):
            idle_barrier(comm)
        raise
    if comm.size > 1:
        idle_barrier(comm)
    return result
