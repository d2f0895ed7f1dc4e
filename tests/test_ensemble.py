"""Ensembles: validation, reproducible plans, exact probabilities, resumable runs."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from fem_runout.ensemble import load_ensemble, run_ensemble
from fem_runout.ensemble.products import exceedance, percentile_maps, read_stack
from fem_runout.ensemble.sampling import member_parameters
from fem_runout.ensemble.spec import EnsembleSpec
from fem_runout.errors import CaseError

ROOT = Path(__file__).resolve().parents[1]

#: A mound sliding down a 17° plane with Voellmy friction (about 0.1 s per member).
MOUND = {"name": "mound", "method": "tg2",
         "domain": {"extent": [0, 60, 0, 30], "cells": [30, 15], "boundary": "open"},
         "terrain": {"elevation": "-0.3 * x"},
         "initial": {"depth": "maximum(2 - 0.1*((x-12)**2 + (y-15)**2), 0)"},
         "material": {"density": 1000, "friction": {"law": "voellmy", "mu": 0.2, "xi": 500}},
         "time": {"end": 2.0, "cfl": 0.9}, "output": {"every": 2.0}}
#: A lake at rest in a closed flat box: every member's peak depth is its initial depth.
LAKE = {"name": "lake", "method": "tg2",
        "domain": {"extent": [0, 10, 0, 10], "cells": [5, 5], "boundary": "wall"},
        "terrain": {"elevation": "0"}, "initial": {"depth": "1"},
        "material": {"density": 1000, "friction": {"law": "none"}},
        "time": {"end": 0.5, "cfl": 0.9}, "output": {"every": 0.5}}
VARY = {"material.friction.mu": {"distribution": "uniform", "low": 0.1, "high": 0.3},
        "material.friction.xi": {"distribution": "lognormal", "median": 500, "sigma": 0.5,
                                 "low": 100}}


def _files(tmp_path: Path, case: dict, spec: dict) -> tuple[Path, Path]:
    case_path, spec_path = tmp_path / "case.yaml", tmp_path / "ensemble.yaml"
    case_path.write_text(yaml.safe_dump(case))
    spec_path.write_text(yaml.safe_dump(spec))
    return case_path, spec_path


def _spec(**kw) -> EnsembleSpec:
    return EnsembleSpec.model_validate({"members": 8, "vary": VARY, **kw})


@pytest.mark.parametrize(("spec", "message"), [
    ({"members": 4, "vary": {"material.friction.mu": {"distribution": "beta"}}},
     "vary.material.friction.mu.distribution: Input should be 'uniform', 'normal', "
     "'lognormal' or 'values'"),
    ({"members": 4, "vary": {"material.friction.mu": {"distribution": "normal", "mean": 0.2}}},
     "vary.material.friction.mu: normal needs mean, std; missing std"),
    ({"members": 4, "vary": {"material.friction.mu": {"distribution": "uniform", "low": 0.3,
                                                      "high": 0.1}}}, "low must be below high"),
    ({"members": 4, "vary": {"material.friction.muu": {"values": [0.1, 0.2]}}},
     "vary.material.friction.muu: not a numeric key of the case"),
    ({"members": 4, "vary": {"material.friction.mu": {"values": [-0.1]}}},
     "vary.material.friction.mu: not a numeric key of the case"),
    ({"members": 4, "vary": VARY, "sampling": {"plan": "halton"}},
     "sampling.plan: Input should be 'lhs', 'sobol', 'random' or 'factorial'"),
    ({"vary": VARY}, "members is required with sampling.plan lhs"),
    ({"members": 4, "vary": VARY, "colour": 1}, "colour: unknown key"),
])
def test_bad_ensemble_files_name_the_key(tmp_path, spec, message):
    case_path, spec_path = _files(tmp_path, MOUND, spec)
    with pytest.raises(CaseError, match="ensemble.yaml: ") as info:
        load_ensemble(spec_path, case_path)
    assert message in str(info.value)


def test_bad_ensemble_exits_2_and_writes_nothing(tmp_path):
    case_path, spec_path = _files(tmp_path, MOUND, {"members": 2, "vary": {"time.cfl": {
        "distribution": "normal", "mean": 0.9, "std": 0.5}}})  # cfl > 1 for some members
    out = tmp_path / "out"
    res = subprocess.run([sys.executable, "-m", "fem_runout", "ensemble", str(case_path),
                          str(spec_path), "--out", str(out)], capture_output=True, text=True,
                         timeout=120, cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("error: ") and "Traceback" not in res.stderr
    assert "member" in res.stderr and "time.cfl" in res.stderr
    assert not out.exists()


@pytest.mark.parametrize("plan", ["lhs", "sobol", "random"])
def test_plan_is_reproducible_from_its_seed(plan):
    a = member_parameters(_spec(sampling={"plan": plan, "seed": 7}))
    b = member_parameters(_spec(sampling={"plan": plan, "seed": 7}))
    c = member_parameters(_spec(sampling={"plan": plan, "seed": 8}))
    assert a == b and a != c and len(a) == 8


def test_latin_hypercube_strata_and_distributions():
    members = member_parameters(_spec(members=2000, sampling={"plan": "lhs", "seed": 1}))
    mu = np.array([m["material.friction.mu"] for m in members])
    xi = np.array([m["material.friction.xi"] for m in members])
    # one sample in each of the 2000 equal-probability strata of the uniform variable
    assert sorted(np.floor((mu - 0.1) / 0.2 * 2000).astype(int)) == list(range(2000))
    assert xi.min() >= 100.0
    # log-normal truncated below at 100 (z = -3.2): the median moves by 0.07 % only
    assert abs(np.median(xi) / 500.0 - 1.0) < 0.01
    assert abs(np.std(np.log(xi)) / 0.5 - 1.0) < 0.02


def test_factorial_plan_is_every_combination():
    spec = EnsembleSpec.model_validate({"sampling": {"plan": "factorial"}, "vary": {
        "material.friction.mu": {"values": [0.1, 0.2, 0.3]},
        "material.friction.xi": {"values": [200, 2000]}}})
    members = member_parameters(spec)
    assert len(members) == 6
    assert {(m["material.friction.mu"], m["material.friction.xi"]) for m in members} == \
        {(a, b) for a in (0.1, 0.2, 0.3) for b in (200.0, 2000.0)}


def test_exceedance_and_percentiles_are_exact():
    stack = np.array([[[0.0, 0.2]], [[0.1, 0.6]], [[0.5, np.nan]], [[1.0, 2.0]]])
    assert exceedance(stack, 0.1).tolist() == [[0.75, 1.0]]  # the NaN member has no data
    assert exceedance(stack, 1.0).tolist() == [[0.25, 1 / 3]]
    maps = percentile_maps(stack, (50.0,))
    assert maps["mean"].tolist() == [[0.4, 0.7]] and maps["p50"].tolist() == [[0.3, 0.4]]


def test_probabilities_exact_on_four_members_with_known_outcomes(tmp_path):
    depths = [0.05, 0.2, 0.6, 1.2]  # a lake at rest: each member's peak depth is its depth
    case_path, spec_path = _files(tmp_path, LAKE, {
        "sampling": {"plan": "factorial"}, "vary": {"initial.depth": {"values": depths}},
        "thresholds": {"depth": [0.1, 0.5, 1.0]}, "percentiles": [50]})
    result = run_ensemble(case_path, spec_path, out=tmp_path / "out")
    assert result.summary["members"] == 4 and result.summary["failed"] == 0
    for th, expected in ((0.1, 0.75), (0.5, 0.5), (1.0, 0.25)):
        p, _ = read_stack([result.out], f"probability_depth_ge_{th:g}m")
        assert np.all(p == expected), (th, np.unique(p))
    mean, _ = read_stack([result.out], "peak_depth_mean")
    assert np.allclose(mean, np.mean(depths), rtol=1e-12, atol=0)


def _products(out: Path) -> dict[str, np.ndarray]:
    names = sorted(p.stem for p in out.glob("*.tif"))
    maps = {n: read_stack([out], n)[0] for n in names}
    rows = (out / "members.csv").read_text().splitlines()
    head = rows[0].split(",")
    keep = [i for i, h in enumerate(head) if h != "wall_time"]
    maps["csv"] = [[r.split(",")[i] for i in keep] for r in rows]
    return maps


def test_killed_ensemble_resumes_to_the_same_products(tmp_path):
    slow = {**MOUND, "domain": {**MOUND["domain"], "cells": [90, 45]}, "time": {"end": 6.0}}
    case_path, spec_path = _files(tmp_path, slow, {"members": 6, "vary": VARY,
                                                    "sampling": {"seed": 5}})
    whole = run_ensemble(case_path, spec_path, out=tmp_path / "whole")
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "fem_runout", "ensemble", str(case_path),
                             str(spec_path), "--out", str(out), "--quiet"], cwd=tmp_path)
    deadline = time.time() + 120
    while len(list(out.glob("members/*/member.json"))) < 2 and time.time() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    done = len(list(out.glob("members/*/member.json")))
    assert 2 <= done < 6
    resumed = run_ensemble(case_path, spec_path, out=out)
    assert resumed.ran == 6 - done
    a, b = _products(whole.out), _products(out)
    assert a.keys() == b.keys()
    assert a.pop("csv") == b.pop("csv")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    assert json.loads((out / "ensemble.json").read_text()) == \
        json.loads((whole.out / "ensemble.json").read_text())


@pytest.mark.parametrize("path", sorted((ROOT / "cases" / "ensembles").glob("*.yaml")),
                         ids=lambda p: p.stem)
def test_shipped_ensembles_load_with_their_case(path):
    from fem_runout.ensemble.driver import prepare
    from fem_runout.terrain.paths import data_folder

    case = ROOT / "cases" / path.name  # cases/ensembles/<name>.yaml varies cases/<name>.yaml
    if "${FEM_RUNOUT_DATA}" in case.read_text() and not data_folder().is_dir():
        pytest.skip(f"{case.name} needs the data folder {data_folder()} (FEM_RUNOUT_DATA)")
    plan = prepare(case, path)
    assert len(plan.members) == plan.spec.members
    assert len({m.key for m in plan.members}) == len(plan.members)  # distinct members


def test_ensemble_report_row_has_the_quantiles(tmp_path):
    from fem_runout.bench.ensemble_report import method_rows

    head = "member,key,x,runout_length,travel_angle_deg,affected_area,deposit_volume," \
           "peak_speed_max,peak_depth_max,wall_time,error"
    rows = [f"{k},k{k},0.1,{1000 + 10 * k},30,{1e4 * k},1,{40 + k},2,{10 + k}," for k in range(11)]
    rows.append("11,k11,0.1,,,,,,,,NaN at t = 1 s")  # a failed member is left out
    (tmp_path / "members.csv").write_text("\n".join([head, *rows]) + "\n")
    (tmp_path / "ensemble.json").write_text(json.dumps(
        {"sensitivity": {"runout_length": {"x": -0.5}}}))
    row, lines = method_rows("mpm", tmp_path)
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[1:4] == ["12", "1", "15.0 (10.0–20.0)"]
    assert cells[4] == "1010 / 1050 / 1090"  # P10 / P50 / P90 of 1000 ... 1100
    assert cells[5] == "1.0 / 5.0 / 9.0"  # 1e4 k m² = k ha
    assert lines == ["- DAMPM: Spearman correlation of the run-out with `x` -0.50"]


def test_histograms_of_members_equal_to_round_off(tmp_path):
    """Members equal but for the last bits (64 m and 64 − 4e-14 m) still get their histograms."""
    from fem_runout.ensemble.pictures import draw_histograms, histogram_range

    keys = ("runout_length", "travel_angle_deg", "affected_area", "deposit_volume")
    records = [{"summary": dict.fromkeys(keys, v)} for v in (64.0, 64.0, 64.0 - 4e-14, 64.0)]
    draw_histograms(records, tmp_path / "d.png")
    assert (tmp_path / "d.png").stat().st_size > 0
    lo, hi = histogram_range(np.array([64.0, 64.0 - 4e-14]))
    assert lo == pytest.approx(63.68) and hi == pytest.approx(64.32)
    assert histogram_range(np.array([1.0, 2.0])) is None  # a real spread keeps numpy's own range


def test_members_on_an_outline_mesh_mesh_it_once(tmp_path, monkeypatch):
    import fem_runout.meshing.build as build
    from fem_runout.meshing import cache

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    cache.clear_memory()
    made = []

    def counted(case):
        made.append(case.initial.depth)
        return mesh_outline(case)

    mesh_outline = build.mesh_outline
    monkeypatch.setattr(build, "mesh_outline", counted)
    depths = [0.2, 0.6, 1.2]  # a lake at rest in a walled pentagon, one member per depth
    lake = {**LAKE, "domain": {"outline": [[0, 0], [40, 0], [50, 30], [20, 45], [-5, 25]],
                               "cell_size": 5.0, "boundary": "wall"}}
    case_path, spec_path = _files(tmp_path, lake, {
        "sampling": {"plan": "factorial"}, "vary": {"initial.depth": {"values": depths}},
        "thresholds": {"depth": [0.5, 1.0]}})
    result = run_ensemble(case_path, spec_path, out=tmp_path / "out")
    cache.clear_memory()
    assert result.summary["members"] == 3 and result.summary["failed"] == 0
    assert len(made) == 1  # gmsh once, the other members from the process's cache
    for th, expected in ((0.5, 2 / 3), (1.0, 1 / 3)):
        p, _ = read_stack([result.out], f"probability_depth_ge_{th:g}m")
        inside = p[np.isfinite(p)]
        assert inside.size > 100 and np.all(inside == expected), (th, np.unique(p))
