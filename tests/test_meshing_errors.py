"""Meshes that fit the scene: bad outlines and meshes are refused with a clear message."""

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from fem_runout.config import load_case
from fem_runout.errors import CaseError
from tests.mesh_helpers import LINE, PENTAGON, mesh_case, outline_case, valley_dem, write_msh
from tests.terrain_helpers import X0, Y1, write_polygons

gmsh = pytest.importorskip("gmsh")
shapely = pytest.importorskip("shapely")

ROOT = Path(__file__).resolve().parents[1]


# --- refused input --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("bad")
    lines = d / "lines.geojson"
    import pyogrio

    wkb = np.array([shapely.to_wkb(shapely.LineString(LINE))], dtype=object)
    pyogrio.raw.write(str(lines), wkb, [], [], geometry_type="LineString", driver="GeoJSON",
                      crs="EPSG:31287")
    far_line = d / "far.geojson"
    wkb = np.array([shapely.to_wkb(shapely.LineString([[900, 900], [950, 990]]))], dtype=object)
    pyogrio.raw.write(str(far_line), wkb, [], [], geometry_type="LineString", driver="GeoJSON",
                      crs="EPSG:31287")
    return {
        "lines": lines,
        "far_line": far_line,
        "release_far": write_polygons(d / "rel_far.geojson",
                                      [shapely.box(900, 900, 950, 950)], thickness=[1.0]),
        "triangles": write_msh(d / "tri.msh", recombine=False, groups={"domain": (2, [1])}),
        "second_order": write_msh(d / "q9.msh", order=2),
        "no_2d": write_msh(d / "lines.msh", dim=1),
        "wall_2d": write_msh(d / "wall2d.msh", groups={"wall": (2, [1])}),
        "unknown_group": write_msh(d / "inlet.msh", groups={"inlet": (1, [4])}),
        "both_groups": write_msh(d / "both.msh", groups={"wall": (1, [4]), "open": (1, [4])}),
        "not_msh": write_polygons(d / "outline.geojson", [shapely.Polygon(PENTAGON)]),
        "dem": valley_dem(d),
    }


BAD: list[tuple[str, Any, str]] = [
    ("outline-and-cells", {"cells": [10, 10]}, "domain.cells: not used with domain.outline"),
    ("outline-and-extent", {"extent": [0, 1, 0, 1]}, "domain.extent: not used with"),
    ("outline-and-window", {"window": [0, 1, 0, 1]}, "domain.window: not used with"),
    ("outline-and-mesh", {"mesh": "x.msh"}, "domain.mesh: give either outline or mesh"),
    ("outline-no-cell-size", {"cell_size": None}, "domain.cell_size: required key is missing"),
    ("outline-side-mapping", {"boundary": {"left": "wall"}}, "domain.boundary: must be open or"),
    ("min-above-cell", {"min_size": 20.0}, "domain.min_size: must be <= cell_size (10)"),
    ("refine-size-above", {"refine": [{"kind": "release", "size": 12, "distance": 5}]},
     "domain.refine[0].size: must be >= min_size (2.5) and <= cell_size (10)"),
    ("refine-size-below", {"refine": [{"kind": "terrain", "size": 1}]},
     "domain.refine[0].size: must be >= min_size"),
    ("refine-kind-unknown", {"refine": [{"kind": "river", "size": 5}]},
     "domain.refine[0].kind: 'river' is not a known value; allowed: 'line', 'terrain' or "
     "'release'"),
    ("refine-key-of-other-kind", {"refine": [{"kind": "terrain", "size": 5, "distance": 3}]},
     "domain.refine[0].distance: not used by kind 'terrain'"),
    ("refine-line-no-distance", {"refine": [{"kind": "line", "line": LINE, "size": 5}]},
     "domain.refine[0].distance: required key is missing"),
    ("refine-line-one-point", {"refine": [{"kind": "line", "line": [[0, 0]], "size": 5,
                                           "distance": 9}]},
     "domain.refine[0].line: a line needs at least 2 distinct points"),
    ("refine-not-a-list", {"refine": {"kind": "terrain", "size": 5}},
     "domain.refine: must be a list"),
    ("refine-terrain-no-dem", {"refine": [{"kind": "terrain", "size": 5}]},
     "domain.refine[0]: kind 'terrain' needs terrain.dem"),
    ("refine-release-no-release", {"refine": [{"kind": "release", "size": 5, "distance": 9}]},
     "domain.refine[0]: kind 'release' needs release polygons"),
    ("refine-line-outside", {"refine": [{"kind": "line", "line": "@far_line", "size": 5,
                                         "distance": 9}]},
     "domain.refine[0].line: lies outside domain.outline"),
    ("two-points", {"outline": [[0, 0], [100, 0], [0, 0]]},
     "domain.outline: a polygon needs at least 3 distinct points"),
    ("not-coordinates", {"outline": [[0, 0], [1, "a"], [2, 2]]}, "domain.outline: must be [x, y]"),
    ("self-intersecting", {"outline": [[0, 0], [100, 100], [100, 0], [0, 100]]},
     "domain.outline: is not a valid polygon: Self-intersection"),
    ("too-small", {"outline": [[0, 0], [4, 0], [4, 4], [0, 4]], "min_size": 2.5},
     "domain.outline: is too small for domain.min_size"),
    ("narrow-neck", {"outline": [[0, 0], [100, 0], [100, 48], [200, 48], [200, 0], [300, 0],
                                 [300, 100], [200, 100], [200, 52], [100, 52], [100, 100],
                                 [0, 100]]},
     "domain.outline: is narrower than 2 x domain.min_size"),
    ("short-edge", {"outline": [[0, 0], [100, 0], [100, 100], [1, 100], [0, 100]]},
     "is 1 m long, shorter than domain.min_size"),
    ("outline-file-missing", {"outline": "nowhere.geojson"}, "domain.outline: file"),
    ("outline-file-of-lines", {"outline": "@lines"}, "domain.outline: '"),
    ("outline-not-path", {"outline": 5}, "domain.outline: must be a file path"),
    ("mesh-and-cell-size", {"outline": None, "mesh": "@triangles"},
     "domain.cell_size: not used with domain.mesh"),
]

BAD_MESH: list[tuple[str, Any, str]] = [
    ("missing", {"mesh": "nowhere.msh"}, "domain.mesh: file"),
    ("not-msh", {"mesh": "@not_msh"}, "is not a gmsh .msh file"),
    ("triangles", {"mesh": "@triangles"}, "domain.mesh: holds 2D elements other than 4-node "
     "quadrilaterals (48 of type 'Triangle 3')"),
    ("second-order", {"mesh": "@second_order"}, "(24 of type 'Quadrilateral 9')"),
    ("no-2d", {"mesh": "@no_2d"}, "domain.mesh: holds no 2D elements"),
    ("wall-2d", {"mesh": "@wall_2d"}, "domain.mesh: physical group 'wall' has dimension 2"),
    ("unknown-group", {"mesh": "@unknown_group"}, "1D physical group 1 is named 'inlet'"),
    ("both-groups", {"mesh": "@both_groups"}, "boundary edges are in both groups open and wall"),
    ("side-mapping", {"mesh": "@both_groups", "boundary": {"top": "wall"}},
     "domain.boundary: must be open or wall with domain.mesh"),
    ("refine", {"mesh": "@both_groups", "refine": []}, "domain.refine: not used with"),
    ("min-size", {"mesh": "@both_groups", "min_size": 3}, "domain.min_size: not used with"),
]


def _files(value: Any, files: dict[str, Path]) -> Any:
    if isinstance(value, str) and value.startswith("@"):
        return str(files[value[1:]])
    if isinstance(value, list):
        return [_files(v, files) for v in value]
    if isinstance(value, dict):
        return {k: _files(v, files) for k, v in value.items()}
    return value


@pytest.mark.parametrize(("change", "needle"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_outline_is_refused(bad_files: dict[str, Path], change: dict, needle: str) -> None:
    data = outline_case(**_files(change, bad_files))
    data["domain"] = {k: v for k, v in data["domain"].items() if v is not None}
    with pytest.raises(CaseError) as err:
        load_case(data)
    assert needle in str(err.value)


@pytest.mark.parametrize(("domain", "needle"), [b[1:] for b in BAD_MESH],
                         ids=[b[0] for b in BAD_MESH])
def test_bad_mesh_file_is_refused(bad_files: dict[str, Path], domain: dict, needle: str) -> None:
    data = mesh_case(Path("x"))
    data["domain"] = _files(domain, bad_files)
    with pytest.raises(CaseError) as err:
        load_case(data)
    assert needle in str(err.value)


def test_outline_against_the_dem_and_release(bad_files: dict[str, Path], tmp_path: Path) -> None:
    dem = str(bad_files["dem"])
    inside = [[X0 + 20, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20], [X0 + 20, Y1 - 20]]
    outside = [[X0 - 50, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20]]
    data = outline_case(outline=outside)
    data["terrain"] = {"dem": dem}
    with pytest.raises(CaseError, match=r"domain.outline: reaches outside the DEM 'dem.tif'"):
        load_case(data)
    holes = valley_dem(tmp_path, nodata=True)
    data = outline_case(outline=inside)
    data["terrain"] = {"dem": str(holes)}
    with pytest.raises(CaseError, match=r"domain.outline: 9 points of the area fall on nodata"):
        load_case(data)
    data["terrain"]["fill_nodata"] = True
    assert load_case(data).domain.kind == "outline"
    lonlat = write_polygons(tmp_path / "lonlat.geojson", [shapely.Polygon(inside)],
                            crs="EPSG:4326")
    data = outline_case(outline=str(lonlat))
    data["terrain"] = {"dem": dem}
    with pytest.raises(CaseError, match="domain.outline: its CRS EPSG:4326 differs from the "
                                        "run's EPSG:31287"):
        load_case(data)
    data = outline_case(outline=inside)
    data["terrain"] = {"dem": dem}
    data["initial"] = {"release": {"polygon": str(bad_files["release_far"])}}
    with pytest.raises(CaseError, match="initial.release: the release polygons lie outside "
                                        "domain.outline"):
        load_case(data)


def test_cli_refuses_a_bad_outline_with_exit_code_2(tmp_path: Path) -> None:
    data = outline_case(outline=[[0, 0], [100, 100], [100, 0], [0, 100]])
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(data))
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run([sys.executable, "-m", "fem_runout", "case.yaml"], cwd=tmp_path,
                            env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr
    assert lines[0].startswith("error: case.yaml: domain.outline: is not a valid polygon")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml"]  # nothing written
