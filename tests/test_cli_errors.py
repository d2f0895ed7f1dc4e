"""Malformed input must give one line on stderr, exit code 2, and write nothing."""

import copy
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.cli_helpers import main_in

ROOT = Path(__file__).resolve().parents[1]

GOOD: dict[str, Any] = {
    "name": "strip",
    "domain": {"extent": [0, 10, 0, 1], "cells": [10, 1], "boundary": "wall"},
    "terrain": {"elevation": "0"},
    "initial": {"depth": "where(x <= 5, 1.0, 0)"},
    "material": {"density": 1000, "friction": {"law": "none"}},
    "time": {"end": 0.1, "cfl": 0.5},
    "output": {"dir": "out", "every": 0.05},
}


def _set(data: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    data = copy.deepcopy(data)
    *parents, last = key.split(".")
    node = data
    for part in parents:
        node = node.setdefault(part, {})
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value
    return data


_DELETE = object()

# (id, case file content (mapping or raw text), extra CLI args, text that stderr must contain)
BAD_CASES: list[tuple[str, Any, list[str], str]] = [
    ("unknown-top-level-key", _set(GOOD, "colour", "red"), [], "colour: unknown key"),
    ("unknown-nested-key", _set(GOOD, "material.frictoin", {}), [], "material.frictoin"),
    ("cells-wrong-type", _set(GOOD, "domain.cells", "ten"), [], "domain.cells"),
    ("cells-negative", _set(GOOD, "domain.cells", [-1, 3]), [], "domain.cells"),
    ("density-negative", _set(GOOD, "material.density", -5), [], "material.density"),
    ("gravity-string", _set(GOOD, "gravity", "strong"), [], "gravity"),
    ("end-zero", _set(GOOD, "time.end", 0), [], "time.end"),
    ("end-negative", _set(GOOD, "time.end", -1.0), [], "time.end"),
    ("cfl-zero", _set(GOOD, "time.cfl", 0), [], "time.cfl"),
    ("cfl-negative", _set(GOOD, "time.cfl", -0.5), [], "time.cfl"),
    ("cfl-above-one", _set(GOOD, "time.cfl", 1.5), [], "time.cfl"),
    ("time-missing", _set(GOOD, "time", _DELETE), [], "time: required key is missing"),
    (
        "friction-law-unknown",
        _set(GOOD, "material.friction.law", "mohr"),
        [],
        "material.friction.law",
    ),
    (
        "voellmy-without-xi",
        _set(GOOD, "material.friction", {"law": "voellmy", "mu": 0.2}),
        [],
        "material.friction.xi",
    ),
    (
        "phi-90",
        _set(GOOD, "material.friction", {"law": "coulomb", "phi_deg": 90}),
        [],
        "material.friction.phi_deg",
    ),
    (
        "bingham-incomplete",
        _set(GOOD, "material.rheology", {"law": "bingham", "viscosity": 1}),
        [],
        "material.rheology.yield_stress",
    ),
    ("method-unknown", _set(GOOD, "method", "sph"), [], "method"),
    (
        "boundary-unknown",
        _set(GOOD, "domain.boundary", {"left": "sticky"}),
        [],
        "domain.boundary.left",
    ),
    ("xmin-ge-xmax", _set(GOOD, "domain.extent", [10, 0, 0, 1]), [], "domain.extent"),
    ("expression-unparsable", _set(GOOD, "initial.depth", "1 +"), [], "initial.depth"),
    ("expression-forbidden", _set(GOOD, "initial.depth", "__import__('os')"), [], "initial.depth"),
    (
        "expression-attribute",
        _set(GOOD, "terrain.elevation", "x.__class__"),
        [],
        "terrain.elevation",
    ),
    ("velocity-one-component", _set(GOOD, "initial.velocity", ["0"]), [], "initial.velocity"),
    ("depth-and-free-surface", _set(GOOD, "initial.free_surface", "2"), [], "initial"),
    ("invalid-yaml", "name: strip\ndomain: {extent: [0, 1, 0, 1]\ntime: {end: 1}\n", [], "line"),
    ("duplicate-key", "name: a\nname: b\n", [], "duplicate key 'name'"),
    ("top-level-list", "- name\n", [], "top level must be a mapping"),
    ("set-unknown-key", GOOD, ["--set", "time.ned=3"], "time.ned"),
    ("set-without-equals", GOOD, ["--set", "time.end"], "override 'time.end'"),
    ("set-bad-value", GOOD, ["--set", "time.end=-2"], "time.end"),
    ("method-unknown-in-file", _set(GOOD, "method", "sph"), [], "method"),
    ("particles-per-direction-zero", _set(GOOD, "numerics.particles_per_direction", 0), [],
     "numerics.particles_per_direction"),
    ("flip-above-one", _set(GOOD, "numerics.flip", 1.5), [], "numerics.flip"),
]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.update(NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return env


def _tree(path: Path) -> list[str]:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


def _run(cwd: Path, args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "fem_runout", *args],
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )


def _check_rejected(result: subprocess.CompletedProcess[str], needle: str) -> None:
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert needle in lines[0]


#: Bad cases also run through the real ``python -m fem_runout`` (the others call
#: :func:`fem_runout.cli.main` in this process: the same code, without a second of start-up).
THROUGH_PROCESS = {"unknown-top-level-key", "invalid-yaml", "set-bad-value", "phi-90"}


@pytest.mark.parametrize(("name", "content", "args", "needle"), BAD_CASES,
                         ids=[c[0] for c in BAD_CASES])
def test_bad_case_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                              monkeypatch: pytest.MonkeyPatch, name: str, content: Any,
                              args: list[str], needle: str) -> None:
    case = tmp_path / "case.yaml"
    case.write_text(content if isinstance(content, str) else yaml.safe_dump(content))
    before = _tree(tmp_path)
    if name in THROUGH_PROCESS:
        result = _run(tmp_path, ["case.yaml", *args])
    else:
        result = main_in(tmp_path, ["case.yaml", *args], capsys, monkeypatch)
    _check_rejected(result, needle)
    assert _tree(tmp_path) == before
    assert not (tmp_path / "out").exists()
    assert not (tmp_path / "results").exists()


def test_missing_case_file(tmp_path: Path) -> None:
    result = _run(tmp_path, ["missing.yaml"])
    _check_rejected(result, "case file 'missing.yaml' does not exist")
    assert _tree(tmp_path) == []


def test_non_empty_output_dir_needs_overwrite(tmp_path: Path) -> None:
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(GOOD))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "old.txt").write_text("keep me")
    before = _tree(tmp_path)
    result = _run(tmp_path, ["case.yaml"])
    _check_rejected(result, "output dir 'out' is not empty; pass --overwrite")
    assert _tree(tmp_path) == before
    assert (tmp_path / "out" / "old.txt").read_text() == "keep me"


def test_out_option_checks_its_directory(tmp_path: Path) -> None:
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(GOOD))
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "x").write_text("")
    result = _run(tmp_path, ["case.yaml", "--out", "elsewhere", "--set", "time.end=0.2"])
    _check_rejected(result, "output dir 'elsewhere' is not empty")


def test_usage_error_exits_2(tmp_path: Path) -> None:
    result = _run(tmp_path, ["case.yaml", "--method", "sph"])
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "--method" in result.stderr


def test_help(tmp_path: Path) -> None:
    result = _run(tmp_path, ["--help"])
    assert result.returncode == 0
    assert "--set" in result.stdout and "--overwrite" in result.stdout


def test_main_returns_2_in_process(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from fem_runout.cli import main

    (tmp_path / "case.yaml").write_text(yaml.safe_dump(_set(GOOD, "time.cfl", 2)))
    assert main([str(tmp_path / "case.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "time.cfl: must be > 0 and <= 1, got 2" in err


#: Modules a rejected case must not load (the solver stack: 2-3 s of imports).
HEAVY = ("dolfinx", "petsc4py", "numba", "pyvista", "gmsh", "rasterio")
LIGHT = """
import sys
from fem_runout.cli import main
code = main(sys.argv[1:])
print(",".join(m for m in {heavy!r} if m in sys.modules))
sys.exit(code)
"""


@pytest.mark.parametrize("law", [{"law": "voellmy", "mu": 0.2},
                                 {"law": "coulomb", "phi_deg": 90}])
def test_a_rejected_case_loads_no_solver_module(tmp_path: Path, law: dict[str, Any]) -> None:
    """The command line validates the whole case (friction laws' parameters included) before
    it imports DOLFINx, PETSc, numba or the renderers: a typo's message comes in about 1 s."""
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(_set(GOOD, "material.friction", law)))
    result = subprocess.run([sys.executable, "-c", LIGHT.format(heavy=HEAVY), "case.yaml"],
                            cwd=tmp_path, env=_env(), capture_output=True, text=True,
                            timeout=120)
    _check_rejected(result, "material.friction.")
    assert result.stdout.strip() == ""
