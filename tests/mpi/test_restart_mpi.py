"""Restart on another rank count (run under ``mpiexec -n 2``, also on 3): a checkpoint written
on 1 rank continues on all, one written on all continues on 1, with the uninterrupted result."""

from __future__ import annotations

from pathlib import Path

from mpi4py import MPI

# isort: split

import numpy as np
import pytest

from fem_runout.api import run
from tests.idle import idle_barrier
from tests.test_checkpoint import FINAL, SUMMARY, case_of

WORLD = MPI.COMM_WORLD


def _folder(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("restart") if WORLD.rank == 0 else None
    return Path(WORLD.bcast(str(path) if path else None, root=0))


def _close(a, b) -> None:
    """Rank 0: the same run to 1e-10 (relative L1 of every field; the summary's numbers)."""
    for key in FINAL:
        x, y = getattr(a, key), getattr(b, key)
        assert np.abs(x - y).sum() <= 1e-10 * max(np.abs(x).sum(), 1e-300), key
    for key in SUMMARY:
        assert a.summary[key] == pytest.approx(b.summary[key], rel=1e-10, abs=1e-300), key
    assert a.steps == b.steps


def _checkpoints(folder: Path) -> list[Path]:
    return sorted((folder / "checkpoints").glob("checkpoint_*.h5"))


@pytest.mark.parametrize("method", ["tg2", "mpm"])
@pytest.mark.parametrize("name", ["bingham", "auto"])
def test_restart_on_another_rank_count(tmp_path_factory, method, name):
    root = _folder(tmp_path_factory)
    whole = run(case_of(name, method, root / "whole"), comm=WORLD)
    every = (f"output.checkpoint.every={3 if name == 'auto' else 0.3}",
             "output.checkpoint.keep=10")
    # all ranks -> all ranks (bitwise) and all ranks -> 1 rank
    run(case_of(name, method, root / "all", *every), comm=WORLD)
    mid = _checkpoints(root / "all")[-2]  # mid-run (end: auto: the flow settling)
    same = run(case_of(name, method, root / "all"), comm=WORLD, restart=mid)
    if WORLD.rank == 0:
        for key in FINAL:
            assert np.array_equal(getattr(whole, key), getattr(same, key)), key
        one = run(case_of(name, method, root / "one_from_all"), comm=MPI.COMM_SELF,
                  restart=mid)
        _close(whole, one)
        # 1 rank -> all ranks: the checkpoint is written by rank 0 alone
        run(case_of(name, method, root / "one", *every), comm=MPI.COMM_SELF)
    idle_barrier(WORLD)  # the other ranks sleep while rank 0 runs alone
    many = run(case_of(name, method, root / "one"), comm=WORLD,
               restart=_checkpoints(root / "one")[-2])
    if WORLD.rank == 0:
        _close(whole, many)


@pytest.mark.parametrize("method", ["tg2", "mpm"])
def test_restart_on_a_part_of_the_mesh_is_refused_on_every_rank(tmp_path_factory, method):
    """Every node of the smaller mesh is one of the checkpoint's, on every rank: refused."""
    from fem_runout.errors import CaseError

    root = _folder(tmp_path_factory)
    run(case_of("hemisphere", method, root / "a", "time.end=0.3",
                "output.checkpoint.every=0.3"), comm=WORLD)
    part = case_of("hemisphere", method, root / "a", "domain.cells=[30,15]",
                   "domain.extent=[0,50,0,25]")
    with pytest.raises(CaseError, match="domain.cells: \\[30, 30\\] in the checkpoint"):
        run(part, comm=WORLD, restart=_checkpoints(root / "a")[-1])
