"""Meshes that fit the scene: domain.outline / domain.mesh, the gmsh model, the checks."""

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from fem_runout.config import dump_resolved, load_case
from fem_runout.errors import CaseError
from fem_runout.meshing import build_model, case_mesh, gmsh_session, mesh_quality, read_model
from fem_runout.terrain.paths import data_folder
from tests.terrain_helpers import RES, X0, Y1, write_dem, write_polygons

gmsh = pytest.importorskip("gmsh")
shapely = pytest.importorskip("shapely")

ROOT = Path(__file__).resolve().parents[1]
PENTAGON = [[0, 0], [400, 0], [500, 300], [200, 450], [-50, 250]]
LINE = [[0, 100], [450, 200]]


def _case(**domain: Any) -> dict[str, Any]:
    base: dict[str, Any] = {"outline": PENTAGON, "cell_size": 10.0}
    return {"name": "outline", "domain": {**base, **domain}, "initial": {"depth": "1"},
            "time": {"end": 1.0}}


def _model_arrays() -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """Node tags, element types by dimension and node coordinates of the current model."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    types = {d: np.asarray(gmsh.model.mesh.getElementTypes(d)) for d in (1, 2, 3)}
    return tags, types, xyz.reshape(-1, 3)


def _topological_boundary(quads: np.ndarray) -> set[tuple[int, int]]:
    edges = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    keys, counts = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    return {tuple(e) for e in keys[counts == 1].tolist()}


def _mean_edge(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    p = mesh.nodes[mesh.quads]
    return p.mean(axis=1), np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2).mean(axis=1)


# --- the generated mesh -------------------------------------------------------------------


def test_outline_mesh_is_quads_covering_the_polygon_once() -> None:
    case = load_case(_case(boundary="wall"))
    assert case.domain.kind == "outline"
    assert case.domain.extent == (-50.0, 500.0, 0.0, 450.0)
    assert case.domain.min_size == 2.5  # default cell_size / 4
    with gmsh_session():
        build_model(case)
        tags, types, xyz = _model_arrays()
        groups = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in
                  gmsh.model.getPhysicalGroups()}
        mesh = read_model()
        quality = mesh_quality()
    assert types[2].tolist() == [3] and types[3].size == 0  # 4-node quadrilaterals only
    assert types[1].tolist() == [1]
    assert np.array_equal(np.sort(tags), np.arange(1, len(tags) + 1))  # contiguous 1..N
    assert np.all(xyz[:, 2] == 0)
    assert groups == {"domain": (2, 1), "wall": (1, 2)}  # the empty "open" is left out
    area = shapely.Polygon(PENTAGON).area
    assert abs(quality["area"] - area) <= 1e-9 * area
    assert quality["min_scaled_jacobian"] > 0.5  # convex, counterclockwise, well shaped
    assert 20 < quality["min_angle"] and quality["max_angle"] < 160
    bnd = _topological_boundary(mesh.quads)
    tagged = [tuple(sorted(e)) for e in mesh.groups["wall"].tolist()]
    assert len(tagged) == len(set(tagged)) == len(bnd) and set(tagged) == bnd
    assert len(mesh.groups["open"]) == 0


def test_outline_with_a_hole_from_a_file(tmp_path: Path) -> None:
    outer = shapely.Polygon([(0, 0), (200, 0), (200, 120), (0, 120)])
    hole = shapely.Polygon([(80, 40), (120, 40), (120, 80), (80, 80)])
    path = write_polygons(tmp_path / "outline.geojson", [outer.difference(hole)])
    case = load_case(_case(outline=str(path), cell_size=8.0))
    with gmsh_session():
        mesh = case_mesh(case)
    q = mesh_quality(mesh.nodes, mesh.quads)
    assert abs(q["area"] - (200 * 120 - 40 * 40)) <= 1e-9 * 22400
    ring_nodes = np.unique(mesh.groups["open"])
    x, y = mesh.nodes[ring_nodes].T
    on_hole = (np.abs(x - 100) <= 20 + 1e-9) & (np.abs(y - 60) <= 20 + 1e-9)
    assert on_hole.sum() >= 8  # the hole's edge is boundary too
    assert len(mesh.groups["wall"]) == 0


def test_refine_line_size() -> None:
    refine = [{"kind": "line", "line": LINE, "size": 3.0, "distance": 60.0}]
    case = load_case(_case(refine=refine))
    with gmsh_session():
        mesh = case_mesh(case)
    centre, edge = _mean_edge(mesh)
    d = shapely.distance(shapely.LineString(LINE), shapely.points(centre))
    near, far = edge[d < 3.0].mean(), edge[d > 80.0].mean()
    assert 3.0 / 1.3 < near < 3.0 * 1.3
    assert 10.0 / 1.3 < far < 10.0 * 1.3
    assert edge[(d > 25) & (d < 35)].mean() < far  # graded in between


def test_refine_release_size(tmp_path: Path) -> None:
    release = shapely.Polygon([(150, 150), (250, 150), (250, 220), (150, 220)])
    path = write_polygons(tmp_path / "rel.geojson", [release], thickness=[1.0])
    data = _case(refine=[{"kind": "release", "size": 4.0, "distance": 50.0}])
    data["initial"] = {"release": {"polygon": str(path)}}
    case = load_case(data)
    with gmsh_session():
        mesh = case_mesh(case)
    centre, edge = _mean_edge(mesh)
    d = shapely.distance(release, shapely.points(centre))
    assert 4.0 / 1.3 < edge[d == 0].mean() < 4.0 * 1.3  # inside the release too
    assert 10.0 / 1.3 < edge[d > 70].mean() < 10.0 * 1.3


def _valley_dem(tmp_path: Path, nodata: bool = False) -> Path:
    """A 400 m x 300 m DEM: a plane with a sharp ridge along y = 150 m."""
    rows, cols = 60, 80
    xc = X0 + RES * (np.arange(cols) + 0.5)
    yc = Y1 - RES * (np.arange(rows) + 0.5)
    x, y = np.meshgrid(xc, yc)
    z = 100 + 0.2 * (x - X0) + 30 * np.exp(-(((y - (Y1 - 150)) / 20) ** 2))
    if nodata:
        z[30:33, 40:43] = np.nan
    return write_dem(tmp_path / "dem.tif", z)


def test_refine_terrain_size(tmp_path: Path) -> None:
    dem = _valley_dem(tmp_path)
    outline = [[X0 + 20, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20], [X0 + 20, Y1 - 20]]
    data = _case(outline=outline, refine=[{"kind": "terrain", "size": 4.0}])
    data["terrain"] = {"dem": str(dem)}
    case = load_case(data)
    assert case.domain.refine[0].tolerance == 0.25  # the default
    with gmsh_session():
        mesh = case_mesh(case)
    centre, edge = _mean_edge(mesh)
    ridge = np.abs(centre[:, 1] - (Y1 - 150)) < 6
    plane = np.abs(centre[:, 1] - (Y1 - 150)) > 60
    assert edge[ridge].mean() < 0.6 * edge[plane].mean()
    assert 10.0 / 1.3 < edge[plane].mean() < 10.0 * 1.3


def test_terrain_size_formula() -> None:
    from fem_runout.config.domain import RefineSpec
    from fem_runout.meshing.fields import terrain_size

    item = RefineSpec(kind="terrain", size=2.0, tolerance=0.25)
    x = np.arange(200) * 1.0
    flat = terrain_size(np.tile(0.3 * x, (50, 1)), 1.0, item, 20.0)
    assert np.allclose(flat, 20.0)  # no curvature: cell_size
    k = 0.01  # z = k x^2: lambda = 2k, h = sqrt(8 tol / 2k) = 10 m
    curved = terrain_size(np.tile(k * (x - 100) ** 2, (50, 1)), 1.0, item, 20.0)
    assert np.allclose(curved[25, 80:121], 10.0, rtol=0.01)  # up to the discrete filter


def test_same_case_same_mesh() -> None:
    refine = [{"kind": "line", "line": LINE, "size": 4.0, "distance": 40.0}]
    case = load_case(_case(refine=refine))
    arrays = []
    for _ in range(2):
        with gmsh_session():
            build_model(case)
            tags, xyz, _ = gmsh.model.mesh.getNodes()
            etypes, etags, conn = gmsh.model.mesh.getElements(2)
            arrays.append((tags.copy(), xyz.copy(), conn[0].copy()))
    (t0, x0, c0), (t1, x1, c1) = arrays
    assert np.array_equal(t0, t1) and np.array_equal(x0, x1) and np.array_equal(c0, c1)


def test_build_model_twice_in_one_session_replaces_the_model() -> None:
    case = load_case(_case(cell_size=25.0))
    with gmsh_session():
        build_model(case)
        build_model(case)
        assert gmsh.model.list().count("fem_runout") == 1
        assert gmsh.model.getCurrent() == "fem_runout"
    assert not gmsh.isInitialized()


def test_gmsh_session_nests() -> None:
    with gmsh_session():
        with gmsh_session():
            pass
        assert gmsh.isInitialized()  # the inner session leaves the outer one running
        assert gmsh.option.getNumber("General.Terminal") == 0
    assert not gmsh.isInitialized()


def test_dolfinx_reads_the_model() -> None:
    import dolfinx.io.gmsh

    refine = [{"kind": "line", "line": LINE, "size": 5.0, "distance": 40.0}]
    case = load_case(_case(refine=refine, cell_size=20.0))
    with gmsh_session():
        build_model(case)
        mesh = read_model()
        data = dolfinx.io.gmsh.model_to_mesh(gmsh.model, MPI.COMM_SELF, 0, gdim=2)
    topology = data.mesh.topology
    assert topology.cell_type.name == "quadrilateral"
    assert topology.index_map(2).size_local == len(mesh.quads)
    assert data.mesh.geometry.x.shape[0] == len(mesh.nodes)
    assert data.physical_groups["domain"] == (2, 1)
    assert data.physical_groups["open"] == (1, 1)
    values, counts = np.unique(data.facet_tags.values, return_counts=True)
    assert values.tolist() == [1] and counts.tolist() == [len(mesh.groups["open"])]
    topology.create_connectivity(1, 2)
    import dolfinx.mesh

    exterior = dolfinx.mesh.exterior_facet_indices(topology)
    assert np.array_equal(np.sort(data.facet_tags.indices), np.sort(exterior))


def test_rectangle_through_build_model() -> None:
    case = load_case({"name": "r", "domain": {"extent": [0, 4, 0, 2], "cells": [4, 2],
                                              "boundary": {"left": "wall", "top": "wall"}},
                      "initial": {"depth": "1"}, "time": {"end": 1}})
    assert case.domain.kind == "rectangle"
    with gmsh_session():
        build_model(case)
        mesh = read_model()
    assert len(mesh.quads) == 8 and len(mesh.nodes) == 15
    wall = mesh.nodes[mesh.groups["wall"]].mean(axis=1)
    assert len(wall) == 2 + 4 and np.all((wall[:, 0] == 0) | (wall[:, 1] == 2))
    assert len(mesh.groups["open"]) == 2 + 4


# --- .msh files -----------------------------------------------------------------------------


def _write_msh(path: Path, *, recombine: bool = True, order: int = 1, groups: Any = None,
               dim: int = 2) -> Path:
    """A 30 m x 20 m rectangle meshed by gmsh (transfinite 6 x 4), written to ``path``.

    ``groups``: ``{name: (dim, [entity tags])}``; curves 1..4 are bottom, right, top, left.
    """
    with gmsh_session():
        gmsh.model.add("test")
        pts = [gmsh.model.geo.addPoint(x, y, 0) for x, y in [(0, 0), (30, 0), (30, 20), (0, 20)]]
        lines = [gmsh.model.geo.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
        surface = gmsh.model.geo.addPlaneSurface([gmsh.model.geo.addCurveLoop(lines)])
        for c, n in zip(lines, (7, 5, 7, 5), strict=True):
            gmsh.model.geo.mesh.setTransfiniteCurve(c, n)
        gmsh.model.geo.mesh.setTransfiniteSurface(surface)
        if recombine:
            gmsh.model.geo.mesh.setRecombine(2, surface)
        gmsh.model.geo.synchronize()
        for name, (d, tags) in (groups or {}).items():
            gmsh.model.addPhysicalGroup(d, tags, name=name)
        gmsh.model.mesh.generate(dim)
        if order > 1:
            gmsh.model.mesh.setOrder(order)
        gmsh.option.setNumber("Mesh.SaveAll", 1)
        gmsh.write(str(path))
    return path


def _mesh_case(path: Path, **domain: Any) -> dict[str, Any]:
    return {"name": "m", "domain": {"mesh": str(path), **domain}, "initial": {"depth": "1"},
            "time": {"end": 1.0}}


def test_msh_untagged_edges_take_the_boundary(tmp_path: Path) -> None:
    path = _write_msh(tmp_path / "rect.msh", groups={"wall": (1, [2])})  # the right side
    case = load_case(_mesh_case(path))
    assert case.domain.kind == "file"
    assert case.domain.extent == (0.0, 30.0, 0.0, 20.0)
    assert case.domain.cell_size == pytest.approx(5.0)  # the mean edge length
    with gmsh_session():
        mesh = case_mesh(case)
    assert len(mesh.quads) == 24
    wall = mesh.nodes[mesh.groups["wall"]]
    assert len(wall) == 4 and np.all(wall[..., 0] == 30)
    assert len(mesh.groups["open"]) == 2 * 6 + 4  # default boundary: open
    walled = load_case(_mesh_case(path, boundary="wall"))
    with gmsh_session():
        assert len(case_mesh(walled).groups["wall"]) == 20


def test_curved_channel_case() -> None:
    case = load_case(ROOT / "cases" / "curved_channel.yaml")
    assert case.domain.kind == "file"
    assert case.domain.extent == (-50.0, 50.0, -50.0, 50.0)
    with gmsh_session():
        build_model(case)
        mesh = read_model()
        q = mesh_quality()
    assert q["cells"] == 3260 and q["min_scaled_jacobian"] > 0.99
    assert len(mesh.groups["open"]) == 20  # the outlet end, y = 50
    assert np.allclose(mesh.nodes[mesh.groups["open"]][..., 1], 50.0)
    assert len(mesh.groups["wall"]) == 2 * 50 + 2 * 50 + 2 * 63 + 20
    depth = case.initial_depth(mesh.nodes[:, 0], mesh.nodes[:, 1])
    assert depth.max() == 1.0 and depth.min() == 0.0


def test_resolved_case_reloads_anywhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "in").mkdir()
    write_polygons(tmp_path / "in" / "outline.geojson", [shapely.Polygon(PENTAGON)])
    data = _case(outline="in/outline.geojson",
                 refine=[{"kind": "line", "line": LINE, "size": 5.0, "distance": 30.0}])
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(data))
    case = load_case(tmp_path / "case.yaml")
    text = dump_resolved(case)
    assert "extent" not in text and "boundary: open" in text
    monkeypatch.chdir(ROOT)
    assert load_case(yaml.safe_load(text)) == case
    path = _write_msh(tmp_path / "in" / "rect.msh")
    (tmp_path / "mesh.yaml").write_text(yaml.safe_dump(_mesh_case(Path("in/rect.msh"))))
    case = load_case(tmp_path / "mesh.yaml")
    assert case.domain.mesh == str(path.resolve())
    assert load_case(yaml.safe_load(dump_resolved(case))) == case


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
        "triangles": _write_msh(d / "tri.msh", recombine=False, groups={"domain": (2, [1])}),
        "second_order": _write_msh(d / "q9.msh", order=2),
        "no_2d": _write_msh(d / "lines.msh", dim=1),
        "wall_2d": _write_msh(d / "wall2d.msh", groups={"wall": (2, [1])}),
        "unknown_group": _write_msh(d / "inlet.msh", groups={"inlet": (1, [4])}),
        "both_groups": _write_msh(d / "both.msh", groups={"wall": (1, [4]), "open": (1, [4])}),
        "not_msh": write_polygons(d / "outline.geojson", [shapely.Polygon(PENTAGON)]),
        "dem": _valley_dem(d),
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
    data = _case(**_files(change, bad_files))
    data["domain"] = {k: v for k, v in data["domain"].items() if v is not None}
    with pytest.raises(CaseError) as err:
        load_case(data)
    assert needle in str(err.value)


@pytest.mark.parametrize(("domain", "needle"), [b[1:] for b in BAD_MESH],
                         ids=[b[0] for b in BAD_MESH])
def test_bad_mesh_file_is_refused(bad_files: dict[str, Path], domain: dict, needle: str) -> None:
    data = _mesh_case(Path("x"))
    data["domain"] = _files(domain, bad_files)
    with pytest.raises(CaseError) as err:
        load_case(data)
    assert needle in str(err.value)


def test_outline_against_the_dem_and_release(bad_files: dict[str, Path], tmp_path: Path) -> None:
    dem = str(bad_files["dem"])
    inside = [[X0 + 20, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20], [X0 + 20, Y1 - 20]]
    outside = [[X0 - 50, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20]]
    data = _case(outline=outside)
    data["terrain"] = {"dem": dem}
    with pytest.raises(CaseError, match=r"domain.outline: reaches outside the DEM 'dem.tif'"):
        load_case(data)
    holes = _valley_dem(tmp_path, nodata=True)
    data = _case(outline=inside)
    data["terrain"] = {"dem": str(holes)}
    with pytest.raises(CaseError, match=r"domain.outline: 9 points of the area fall on nodata"):
        load_case(data)
    data["terrain"]["fill_nodata"] = True
    assert load_case(data).domain.kind == "outline"
    lonlat = write_polygons(tmp_path / "lonlat.geojson", [shapely.Polygon(inside)],
                            crs="EPSG:4326")
    data = _case(outline=str(lonlat))
    data["terrain"] = {"dem": dem}
    with pytest.raises(CaseError, match="domain.outline: its CRS EPSG:4326 differs from the "
                                        "run's EPSG:31287"):
        load_case(data)
    data = _case(outline=inside)
    data["terrain"] = {"dem": dem}
    data["initial"] = {"release": {"polygon": str(bad_files["release_far"])}}
    with pytest.raises(CaseError, match="initial.release: the release polygons lie outside "
                                        "domain.outline"):
        load_case(data)


def test_cli_refuses_a_bad_outline_with_exit_code_2(tmp_path: Path) -> None:
    data = _case(outline=[[0, 0], [100, 100], [100, 0], [0, 100]])
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


# --- the avaKot corridor --------------------------------------------------------------------


@pytest.mark.skipif(not (data_folder() / "avaKot").is_dir(),
                    reason="avaKot data not found (FEM_RUNOUT_DATA)")
def test_avakot_corridor_case() -> None:
    case = load_case(ROOT / "cases" / "avakot_corridor.yaml")
    d = case.domain
    assert d.kind == "outline" and d.cell_size == 10 and d.min_size == 5
    assert [r.kind for r in d.refine] == ["line", "release"]
    assert case.terrain.crs == "EPSG:31287"
    with gmsh_session():
        mesh = case_mesh(case)
    q = mesh_quality(mesh.nodes, mesh.quads)
    import pyogrio

    poly = shapely.from_wkb(pyogrio.raw.read(d.outline)[2])[0]
    assert abs(q["area"] - poly.area) <= 1e-9 * poly.area
    assert q["min_scaled_jacobian"] > 0.5 and 10_000 < q["cells"] < 25_000
    centre, edge = _mean_edge(mesh)
    thalweg = shapely.from_wkb(pyogrio.raw.read(d.refine[0].line)[2])[0]
    release = shapely.from_wkb(pyogrio.raw.read(
        case.resolve_input(case.initial.release[0].polygon))[2])[0]
    away = (shapely.distance(thalweg, shapely.points(centre)) > 80) & \
        (shapely.distance(release, shapely.points(centre)) > 120)
    assert 5 / 1.3 < edge[shapely.distance(thalweg, shapely.points(centre)) < 5].mean() < 5 * 1.3
    assert 10 / 1.3 < edge[away].mean() < 10 * 1.3
    depth = case.initial_depth(mesh.nodes[:, 0], mesh.nodes[:, 1])
    assert depth.max() > 0.9
