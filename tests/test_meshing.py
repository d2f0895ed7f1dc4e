"""Meshes that fit the scene: domain.outline / domain.mesh, the gmsh model, the checks."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from fem_runout.config import dump_resolved, load_case
from fem_runout.meshing import build_model, case_mesh, gmsh_session, mesh_quality, read_model
from fem_runout.terrain.paths import data_folder
from tests.mesh_helpers import LINE, PENTAGON, mesh_case, outline_case, valley_dem, write_msh
from tests.terrain_helpers import X0, Y1, write_polygons

gmsh = pytest.importorskip("gmsh")
shapely = pytest.importorskip("shapely")

ROOT = Path(__file__).resolve().parents[1]


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
    case = load_case(outline_case(boundary="wall"))
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
    case = load_case(outline_case(outline=str(path), cell_size=8.0))
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
    case = load_case(outline_case(refine=refine))
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
    data = outline_case(refine=[{"kind": "release", "size": 4.0, "distance": 50.0}])
    data["initial"] = {"release": {"polygon": str(path)}}
    case = load_case(data)
    with gmsh_session():
        mesh = case_mesh(case)
    centre, edge = _mean_edge(mesh)
    d = shapely.distance(release, shapely.points(centre))
    assert 4.0 / 1.3 < edge[d == 0].mean() < 4.0 * 1.3  # inside the release too
    assert 10.0 / 1.3 < edge[d > 70].mean() < 10.0 * 1.3


def test_refine_terrain_size(tmp_path: Path) -> None:
    dem = valley_dem(tmp_path)
    outline = [[X0 + 20, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20], [X0 + 20, Y1 - 20]]
    data = outline_case(outline=outline, refine=[{"kind": "terrain", "size": 4.0}])
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


def test_same_case_same_mesh(monkeypatch: pytest.MonkeyPatch) -> None:
    from fem_runout.meshing.cache import CACHE_ENV, clear_memory

    monkeypatch.setenv(CACHE_ENV, "off")  # gmsh meshes it both times
    refine = [{"kind": "line", "line": LINE, "size": 4.0, "distance": 40.0}]
    case = load_case(outline_case(refine=refine))
    arrays = []
    for _ in range(2):
        clear_memory()
        with gmsh_session():
            build_model(case)
            tags, xyz, _ = gmsh.model.mesh.getNodes()
            etypes, etags, conn = gmsh.model.mesh.getElements(2)
            arrays.append((tags.copy(), xyz.copy(), conn[0].copy()))
    (t0, x0, c0), (t1, x1, c1) = arrays
    assert np.array_equal(t0, t1) and np.array_equal(x0, x1) and np.array_equal(c0, c1)


def test_build_model_twice_in_one_session_replaces_the_model() -> None:
    case = load_case(outline_case(cell_size=25.0))
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
    case = load_case(outline_case(refine=refine, cell_size=20.0))
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


def test_msh_untagged_edges_take_the_boundary(tmp_path: Path) -> None:
    path = write_msh(tmp_path / "rect.msh", groups={"wall": (1, [2])})  # the right side
    case = load_case(mesh_case(path))
    assert case.domain.kind == "file"
    assert case.domain.extent == (0.0, 30.0, 0.0, 20.0)
    assert case.domain.cell_size == pytest.approx(5.0)  # the mean edge length
    with gmsh_session():
        mesh = case_mesh(case)
    assert len(mesh.quads) == 24
    wall = mesh.nodes[mesh.groups["wall"]]
    assert len(wall) == 4 and np.all(wall[..., 0] == 30)
    assert len(mesh.groups["open"]) == 2 * 6 + 4  # default boundary: open
    walled = load_case(mesh_case(path, boundary="wall"))
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
    data = outline_case(outline="in/outline.geojson",
                 refine=[{"kind": "line", "line": LINE, "size": 5.0, "distance": 30.0}])
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(data))
    case = load_case(tmp_path / "case.yaml")
    text = dump_resolved(case)
    assert "extent" not in text and "boundary: open" in text
    monkeypatch.chdir(ROOT)
    assert load_case(yaml.safe_load(text)) == case
    path = write_msh(tmp_path / "in" / "rect.msh")
    (tmp_path / "mesh.yaml").write_text(yaml.safe_dump(mesh_case(Path("in/rect.msh"))))
    case = load_case(tmp_path / "mesh.yaml")
    assert case.domain.mesh == str(path.resolve())
    assert load_case(yaml.safe_load(dump_resolved(case))) == case


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
