"""Ensembles over MPI (run under ``mpiexec -n 2``, also on 3): members handed out to groups
give the results of the same members run one by one."""

from __future__ import annotations

import json
from pathlib import Path

from mpi4py import MPI

# isort: split

import numpy as np
import yaml

from fem_runout.api import run
from fem_runout.ensemble import run_ensemble
from fem_runout.ensemble.driver import prepare
from fem_runout.ensemble.products import read_stack
from tests.test_ensemble import MOUND, VARY

WORLD = MPI.COMM_WORLD
SAME = ("released_volume", "deposit_volume", "affected_area", "peak_depth_max",
        "peak_speed_max", "runout_length", "travel_angle_deg", "steps", "t_end")


def _folder(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("ensemble") if WORLD.rank == 0 else None
    return Path(WORLD.bcast(str(path) if path else None, root=0))


def _write(folder: Path, members: int, ranks_per_member: int) -> tuple[Path, Path]:
    case_path, spec_path = folder / "case.yaml", folder / f"ensemble_{ranks_per_member}.yaml"
    if WORLD.rank == 0:
        case_path.write_text(yaml.safe_dump(MOUND))
        spec_path.write_text(yaml.safe_dump({"members": members, "vary": VARY,
                                             "ranks_per_member": ranks_per_member,
                                             "sampling": {"plan": "sobol", "seed": 11}}))
    WORLD.Barrier()
    return case_path, spec_path


def test_members_on_groups_equal_members_run_one_by_one(tmp_path_factory):
    folder = _folder(tmp_path_factory)
    case_path, spec_path = _write(folder, 5, 1)
    result = run_ensemble(case_path, spec_path, out=folder / "out", comm=WORLD)
    assert result.ran == 5 and result.summary["failed"] == 0
    # the same members run alone on one rank, dealt over the ranks (member i on rank i % size,
    # which need not be the group that ran it in the ensemble)
    plan = prepare(case_path, spec_path, out=folder / "out")
    for member in plan.members[WORLD.rank::WORLD.size]:
        alone = run(plan.cases[member.index], write=False, comm=MPI.COMM_SELF)
        record = json.loads((member.folder(plan.out) / "member.json").read_text())
        for key in SAME:
            assert record["summary"][key] == alone.summary[key], (member.index, key)
        peak, _ = read_stack([member.folder(plan.out)], "peak_depth")
        assert np.nanmax(peak) == alone.summary["peak_depth_max"]


def test_several_ranks_per_member_agree_with_one(tmp_path_factory):
    folder = _folder(tmp_path_factory)
    case_path, spec_two = _write(folder, 3, 2 if WORLD.size % 2 == 0 else WORLD.size)
    _, spec_one = _write(folder, 3, 1)
    two = run_ensemble(case_path, spec_two, out=folder / "two", comm=WORLD)
    if WORLD.rank == 0:
        one = run_ensemble(case_path, spec_one, out=folder / "one", comm=MPI.COMM_SELF)
        for name in ("probability_depth_ge_0.1m", "peak_depth_p90", "peak_depth_mean"):
            a, b = (read_stack([r.out], name)[0] for r in (one, two))
            assert np.nanmax(np.abs(a - b)) <= 1e-10 * np.nanmax(np.abs(a)), name
