"""Dam breaks with the discontinuity on a partition cut and away from it (issue 13).

Run under ``mpiexec -n 2`` and ``-n 3`` (make test does both): Stoker's wet-bed dam break
(depth ratios 10:1 and 100:1) and Ritter's dry-bed one, both methods, the dam on the first
boundary between two ranks' cells and elsewhere. Every run must reach its end without a
negative depth (the runner stops on one), give the same bits as the serial run (every
field and peak) and the exact solution to a few per cent (L1 of h at 400 cells).
"""

import functools
import itertools

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.config import load_case
from fem_runout.mesh import build_discretization
from fem_runout.methods import method_names
from fem_runout.references.norms import l1, nodal_weights
from fem_runout.references.stoker import dam_break_case, exact_depth
from tests.serial_runs import serial_references
from tests.tg2_helpers import assert_same_on_ranks

WORLD = MPI.COMM_WORLD
CELLS = (400, 4)
END = 2.0
#: relative L1 error of h at 400 cells (measured 0.4–1.4 %; first-order fronts allow more)
MAX_ERROR = 0.05


def partition_cuts(comm) -> list[float]:
    """x of the boundaries between the ranks' owned cells of the strip (a straight cut)."""
    disc = build_discretization(comm, (0.0, 100.0, 0.0, 2.0), CELLS, {})
    xc = disc.coords[disc.cell_nodes[: disc.n_owned_cells], 0].mean(axis=1)
    dx = 100.0 / CELLS[0]
    spans = comm.allgather((float(xc.min() - dx / 2), float(xc.max() + dx / 2), xc.size))
    for lo, hi, n in spans:  # whole columns: the cut is a line x = const
        assert n == round((hi - lo) / dx) * CELLS[1]
    return sorted({round(b, 9) for lo, hi, _ in spans for b in (lo, hi)} - {0.0, 100.0})


CUTS = partition_cuts(WORLD)


def test_the_strip_is_cut_into_one_piece_per_rank():
    assert len(CUTS) == WORLD.size - 1


METHODS, WHERE, RATIOS = method_names(), ("cut", "away"), (0.1, 0.01, 0.0)


def _dam(where):
    return CUTS[0] if where == "cut" else 40.0


def _case(method, where, h_r):
    return load_case(dam_break_case(1.0, h_r, _dam(where), CELLS, END, method))


def _serial(method, where, h_r):
    from fem_runout.api import run

    return run(_case(method, where, h_r), write=False, comm=MPI.COMM_SELF)


@pytest.fixture(scope="module")
def serial():
    """The serial run of every dam break below, dealt over the ranks (rank 0 holds them)."""
    return serial_references(WORLD, {key: functools.partial(_serial, *key)
                                     for key in itertools.product(METHODS, WHERE, RATIOS)})


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("where", WHERE)
@pytest.mark.parametrize("h_r", RATIOS, ids=["stoker10", "stoker100", "ritter"])
def test_dam_break_on_and_off_the_cut(method, where, h_r, serial):
    x0 = _dam(where)
    assert (where == "cut") == any(abs(x0 - c) < 1e-9 for c in CUTS)
    case = _case(method, where, h_r)
    par = assert_same_on_ranks(case, WORLD, 0.0, serial=serial and serial[method, where, h_r])
    if WORLD.rank != 0:
        return
    exact = exact_depth(par.x, par.t, 1.0, h_r, x0, case.gravity)
    w = nodal_weights(par.x, par.y)
    err = l1(par.h - exact, w) / l1(exact, w)
    print(f"{method} dam break h_r={h_r} at x0={x0} ({where}) on {WORLD.size} ranks: "
          f"L1 {err:.3e}, min h {par.h.min():.3e}, {par.steps} steps")
    assert par.t == pytest.approx(END)
    assert np.all(par.h >= 0.0)
    assert err < MAX_ERROR


def test_the_active_set_on_ranks_gives_the_same_bits():
    """Issue 16: TG2-PC's active set grows across the partition cut mid-run (Ritter)."""
    from fem_runout.api import run
    from fem_runout.methods import default_method

    base = dam_break_case(1.0, 0.0, CUTS[0] - 10.0, CELLS, END, default_method())
    on = run(load_case(base), write=False, comm=WORLD)
    off = run(load_case(base, [("numerics.active_set", False)]), write=False, comm=WORLD)
    if WORLD.rank == 0:
        for key in ("h", "hu", "hv", "peak_depth"):
            assert np.array_equal(getattr(on, key), getattr(off, key)), key
        assert on.peak_depth[np.abs(on.x - CUTS[0]) < 1e-9].max() > 0.0  # it crossed the cut
