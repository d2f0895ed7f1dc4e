import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from fem_runout.config import Case, compile_expression, dump_resolved, load_case
from fem_runout.config.geo import data_folder
from fem_runout.errors import CaseError

CASES = Path(__file__).resolve().parents[1] / "cases"

MINIMAL = {
    "name": "tiny",
    "domain": {"extent": [0, 10, 0, 4], "cells": [5, 2]},
    "initial": {"depth": "1"},
    "time": {"end": 2.0},
}


def _case(**changes: object) -> dict:
    data = yaml.safe_load(yaml.safe_dump(MINIMAL))
    data.update(changes)
    return data


def test_defaults_filled() -> None:
    case = load_case(MINIMAL)
    assert isinstance(case, Case)
    assert case.method == "tg2"
    assert case.gravity == 9.81
    assert case.domain.resolved_cells == (5, 2)
    assert case.domain.sides == {"left": "open", "right": "open", "bottom": "open", "top": "open"}
    assert case.terrain.elevation == "0"
    assert case.initial.velocity == ("0", "0")
    assert case.initial.free_surface is None
    assert case.material.density == 1000.0
    assert case.material.friction.law == "none"
    assert case.material.friction.mu_value is None
    assert case.material.rheology.law == "none"
    assert case.time.cfl == 0.9
    assert case.time.max_steps is None and case.time.dt_max is None
    assert case.output.dir == "results/tiny"
    assert case.output.every == pytest.approx(0.2)
    assert case.output.front_threshold == 1e-3
    assert case.output.pictures is True
    assert case.numerics.dry_tolerance == 1e-6
    assert case.numerics.fct is True
    assert case.output_dir == Path("results/tiny")
    assert case.source_dir is None


def test_case_is_frozen() -> None:
    case = load_case(MINIMAL)
    with pytest.raises(ValueError):
        case.name = "other"  # type: ignore[misc]
    with pytest.raises(ValueError):
        case.time.end = 3.0  # type: ignore[misc]


def test_cell_size_gives_cells() -> None:
    domain = {"extent": [0, 300, 0, 20], "cell_size": 0.9}
    case = load_case(_case(domain=domain))
    assert case.domain.cells is None
    assert case.domain.resolved_cells == (333, 22)
    tiny = load_case(_case(domain={"extent": [0, 1, 0, 0.1], "cell_size": 5}))
    assert tiny.domain.resolved_cells == (1, 1)


def test_cells_and_cell_size_exclusive() -> None:
    with pytest.raises(CaseError, match="domain: give exactly one of cells"):
        load_case(_case(domain={"extent": [0, 1, 0, 1], "cells": [1, 1], "cell_size": 1}))
    with pytest.raises(CaseError, match="domain: give exactly one of cells"):
        load_case(_case(domain={"extent": [0, 1, 0, 1]}))


def test_per_side_boundary() -> None:
    domain = {"extent": [0, 1, 0, 1], "cells": [2, 2], "boundary": {"left": "wall", "top": "wall"}}
    case = load_case(_case(domain=domain))
    assert case.domain.sides == {"left": "wall", "right": "open", "bottom": "open", "top": "wall"}
    walls = load_case(_case(domain={**domain, "boundary": "wall"}))
    assert set(walls.domain.sides.values()) == {"wall"}


def test_string_overrides_parsed_as_yaml() -> None:
    case = load_case(
        MINIMAL,
        [
            "time.end=4",
            "domain.cells=[10, 5]",
            "material.friction.law=coulomb",
            "material.friction.phi_deg=30",
            "output.pictures=false",
            "numerics.dry_tolerance=1e-5",
        ],
    )
    assert case.time.end == 4.0
    assert case.domain.resolved_cells == (10, 5)
    assert case.material.friction.law == "coulomb"
    assert case.material.friction.gamma == 1e-2
    assert case.material.friction.mu_value == pytest.approx(math.tan(math.radians(30)))
    assert case.output.pictures is False
    assert case.numerics.dry_tolerance == 1e-5
    assert case.output.every == pytest.approx(0.4)  # default follows the overridden end


def test_mapping_overrides_create_mappings() -> None:
    overrides = {
        "terrain.elevation": "x/10",
        "material.rheology": {"law": "bingham", "viscosity": 2000, "yield_stress": 30},
        "output.dir": "yes",
    }
    case = load_case(MINIMAL, overrides)
    assert case.terrain.elevation == "x/10"
    assert case.material.rheology.viscosity == 2000.0
    assert case.output.dir == "yes"
    assert MINIMAL["time"] == {"end": 2.0}  # the input mapping is not changed


def test_override_errors() -> None:
    with pytest.raises(CaseError, match="must look like key.path=value"):
        load_case(MINIMAL, ["time.end"])
    with pytest.raises(CaseError, match=r"case: time\.ned: unknown key; allowed keys: end, cfl"):
        load_case(MINIMAL, ["time.ned=3"])
    with pytest.raises(CaseError, match=r"'time\.end' is 2\.0, not a mapping"):
        load_case(MINIMAL, ["time.end.x=3"])


def test_error_messages_name_key() -> None:
    cases = [
        (
            _case(material={"frictoin": {}}),
            "case: material.frictoin: unknown key; allowed keys: density, friction, rheology",
        ),
        (
            _case(domain={"extent": [0, 1, 0, 1], "cells": [-1, 3]}),
            "case: domain.cells: must be two positive integers, got [-1, 3]",
        ),
        (
            _case(material={"friction": {"law": "mohr"}}),
            "case: material.friction.law: 'mohr' is not a known law; "
            "allowed: none, coulomb, voellmy",
        ),
        (_case(time={"end": 1, "cfl": 0}), "case: time.cfl: must be > 0 and <= 1, got 0"),
        (
            _case(material={"friction": {"law": "voellmy", "phi_deg": 20}}),
            "case: material.friction.xi: required for law 'voellmy'",
        ),
        (
            _case(material={"friction": {"law": "none", "mu": 0.3}}),
            "case: material.friction.mu: not allowed with law 'none'",
        ),
        (
            _case(material={"friction": {"law": "coulomb"}}),
            "case: material.friction: law 'coulomb' needs exactly one of mu or phi_deg",
        ),
        (
            _case(material={"rheology": {"law": "bingham", "viscosity": 1}}),
            "case: material.rheology.yield_stress: required for law 'bingham'",
        ),
        (
            _case(initial={"velocity": ["0", "x.real"], "depth": "1"}),
            'case: initial.velocity[1]: expression "x.real" is not allowed',
        ),
    ]
    for data, message in cases:
        with pytest.raises(CaseError) as info:
            load_case(data)
        assert str(info.value).startswith(message), str(info.value)


def test_missing_file_and_bad_yaml(tmp_path: Path) -> None:
    with pytest.raises(CaseError, match="case file 'nope.yaml' does not exist"):
        load_case("nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ndomain: [1,\n")
    with pytest.raises(CaseError, match=r"bad.yaml: invalid YAML at line 3"):
        load_case(bad)
    bad.write_text("- 1\n")
    with pytest.raises(CaseError, match="top level must be a mapping"):
        load_case(bad)
    bad.write_text("name: x\nname: y\n")
    with pytest.raises(CaseError, match="duplicate key 'name'"):
        load_case(bad)


def test_dump_resolved_round_trip(tmp_path: Path) -> None:
    case = load_case(
        MINIMAL,
        {
            "material.friction": {"law": "voellmy", "phi_deg": 26, "xi": 500},
            "domain.boundary": {"left": "wall"},
            "time.max_steps": 10,
        },
    )
    text = dump_resolved(case)
    data = yaml.safe_load(text)
    assert data["output"]["dir"] == "results/tiny"
    assert data["material"]["friction"]["gamma"] == 1e-2
    assert data["domain"]["boundary"]["right"] == "open"
    assert load_case(data) == case
    path = tmp_path / "resolved.yaml"
    path.write_text(text)
    again = load_case(path)
    assert again == case
    assert again.source_dir == tmp_path.resolve()


def test_source_dir_and_resolve_input(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "c.yaml"
    path.parent.mkdir()
    path.write_text(yaml.safe_dump(MINIMAL))
    case = load_case(path)
    assert case.source_dir == path.parent.resolve()
    assert case.resolve_input("dem.tif") == path.parent.resolve() / "dem.tif"
    assert case.resolve_input(tmp_path / "x.tif") == tmp_path / "x.tif"
    assert load_case(MINIMAL).resolve_input("dem.tif") == Path.cwd() / "dem.tif"


def test_numbers_accepted_as_expressions() -> None:
    case = load_case(
        _case(initial={"free_surface": 10, "velocity": [0, 0.5]}, terrain={"elevation": "x/5"})
    )
    assert case.initial.free_surface == "10"
    x = np.array([0.0, 25.0, 60.0])
    np.testing.assert_allclose(case.initial_depth(x, 0 * x), [10.0, 5.0, 0.0])
    u, v = case.initial.velocity_fns()
    assert v(x, x)[0] == 0.5


@pytest.mark.parametrize("path", sorted(CASES.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_cases_load(path: Path) -> None:
    if "${FEM_RUNOUT_DATA}" in path.read_text() and not data_folder().is_dir():
        pytest.skip(f"{path.name} needs the data folder {data_folder()} (FEM_RUNOUT_DATA)")
    case = load_case(path)
    assert case.name == path.stem
    assert case.output.dir == f"results/{path.stem}"
    nx, ny = case.domain.resolved_cells
    xmin, xmax, ymin, ymax = case.domain.extent
    x, y = np.meshgrid(np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1))
    depth = case.initial_depth(x, y)
    assert np.all(np.isfinite(depth)) and np.all(depth >= 0) and depth.max() > 0
    assert load_case(yaml.safe_load(dump_resolved(case))) == case


def test_shipped_case_list() -> None:
    names = {p.stem for p in CASES.glob("*.yaml")}
    assert {
        "inclined_dam_break",
        "inclined_dam_break_450",
        "lake_at_rest",
        "hemisphere",
        "ritter",
    } <= names


def test_inclined_dam_break_values() -> None:
    case = load_case(CASES / "inclined_dam_break.yaml")
    assert case.domain.extent == (0.0, 300.0, 0.0, 20.0)
    assert case.domain.resolved_cells == (330, 33)
    assert case.material.density == 1200.0
    assert (case.time.end, case.time.cfl, case.output.every) == (11.0, 0.9, 0.5)
    x = np.array([0.0, 10.0, 20.0, 21.0])
    z = compile_expression(case.terrain.elevation, "terrain.elevation")(x, 0 * x)
    np.testing.assert_allclose(case.initial_depth(x, 0 * x) + z, [100, 100, 100, z[3]])
    lake = load_case(CASES / "lake_at_rest.yaml")
    assert set(lake.domain.sides.values()) == {"wall"}
    ritter = load_case(CASES / "ritter.yaml")
    assert ritter.domain.sides == {"left": "open", "right": "open", "bottom": "wall", "top": "wall"}
