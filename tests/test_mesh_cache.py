"""Outline meshes kept once made (fem_runout.meshing.cache): the same bits, the right key."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fem_runout.config import load_case
from fem_runout.meshing import QuadMesh, case_mesh, gmsh_session
from fem_runout.meshing import cache as mesh_cache
from fem_runout.meshing.outline import mesh_outline
from tests.mesh_helpers import LINE, outline_case, valley_dem
from tests.terrain_helpers import X0, Y1, write_dem, write_polygons

shapely = pytest.importorskip("shapely")
pytest.importorskip("gmsh")

RELEASE = [(X0 + 150, Y1 - 250), (X0 + 250, Y1 - 250), (X0 + 250, Y1 - 180), (X0 + 150, Y1 - 180)]
OUTLINE = [[X0 + 20, Y1 - 280], [X0 + 380, Y1 - 280], [X0 + 380, Y1 - 20], [X0 + 20, Y1 - 20]]


@pytest.fixture
def disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty disk cache of its own, and nothing kept in the process."""
    monkeypatch.setenv(mesh_cache.CACHE_ENV, str(tmp_path / "cache"))
    mesh_cache.clear_memory()
    yield tmp_path / "cache" / "meshes"
    mesh_cache.clear_memory()


def _inputs(tmp_path: Path) -> dict[str, Any]:
    """A case graded by all three refine kinds, its line, release and DEM in files."""
    line = tmp_path / "line.geojson"
    _write_line(line, [[X0 + 20, Y1 - 100], [X0 + 380, Y1 - 140]])
    release = write_polygons(tmp_path / "rel.geojson", [shapely.Polygon(RELEASE)],
                             thickness=[1.0])
    data = outline_case(outline=OUTLINE, cell_size=12.0, refine=[
        {"kind": "line", "line": str(line), "size": 6.0, "distance": 40.0},
        {"kind": "release", "size": 6.0, "distance": 40.0},
        {"kind": "terrain", "size": 6.0}])
    data["terrain"] = {"dem": str(valley_dem(tmp_path))}
    data["initial"] = {"release": {"polygon": str(release)}}
    return data


def _write_line(path: Path, coords: list[list[float]]) -> None:
    import json

    path.write_text(json.dumps({"type": "FeatureCollection", "crs": {
        "type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::31287"}},
        "features": [{"type": "Feature", "properties": {},
                      "geometry": {"type": "LineString", "coordinates": coords}}]}))


def _counted() -> tuple[list[int], Any]:
    calls: list[int] = []

    def make(case):
        calls.append(1)
        return mesh_outline(case)

    return calls, make


def _same(a: QuadMesh, b: QuadMesh) -> bool:
    return (np.array_equal(a.nodes, b.nodes) and np.array_equal(a.quads, b.quads)
            and sorted(a.groups) == sorted(b.groups)
            and all(np.array_equal(a.groups[g], b.groups[g]) for g in a.groups))


def test_a_cached_mesh_is_gmshs_mesh_bit_for_bit(tmp_path: Path, disk: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    case = load_case(_inputs(tmp_path))
    calls, make = _counted()
    with gmsh_session():
        first = mesh_cache.cached_mesh(case, make)
        again = mesh_cache.cached_mesh(case, make)  # from the process
        mesh_cache.clear_memory()
        stored = mesh_cache.cached_mesh(case, make)  # from the disk (a new run)
    assert len(calls) == 1 and again is first
    assert len(list(disk.glob("*.npz"))) == 1 and not list(disk.glob("*.tmp*"))
    monkeypatch.setenv(mesh_cache.CACHE_ENV, "off")
    mesh_cache.clear_memory()
    with gmsh_session():
        fresh = case_mesh(case)  # gmsh again, nothing read
    assert _same(stored, first) and _same(fresh, first)
    assert len(first.quads) > 500 and not first.nodes.flags.writeable


def test_the_key_follows_every_input_of_the_mesh_and_nothing_else(tmp_path: Path) -> None:
    data = _inputs(tmp_path)
    key = mesh_cache.mesh_key(load_case(data))
    same = [("material", {"density": 1500, "friction": {"law": "voellmy", "mu": 0.3,
                                                         "xi": 500}}),
            ("time", {"end": 7.0}), ("method", "mpm"), ("output", {"pictures": False})]
    for section, value in same:
        assert mesh_cache.mesh_key(load_case({**data, section: value})) == key, section
    changed = {
        "cell_size": {**data, "domain": {**data["domain"], "cell_size": 11.0}},
        "smoothing": {**data, "domain": {**data["domain"], "smoothing": 3}},
        "outline": {**data, "domain": {**data["domain"], "outline": [
            [x + 1.0, y] for x, y in OUTLINE]}},
        "fill_nodata": {**data, "terrain": {**data["terrain"], "fill_nodata": True}},
    }
    keys = {name: mesh_cache.mesh_key(load_case(d)) for name, d in changed.items()}
    assert key not in keys.values() and len(set(keys.values())) == len(keys)
    # the same file names, other contents
    _write_line(Path(data["domain"]["refine"][0]["line"]), [[X0 + 20, Y1 - 90],
                                                             [X0 + 380, Y1 - 140]])
    after_line = mesh_cache.mesh_key(load_case(data))
    moved = shapely.affinity.translate(shapely.Polygon(RELEASE), 5.0, 0.0)
    write_polygons(Path(data["initial"]["release"]["polygon"]), [moved], thickness=[1.0])
    after_release = mesh_cache.mesh_key(load_case(data))
    dem = Path(data["terrain"]["dem"])
    import rasterio

    with rasterio.open(dem) as src:
        z = src.read(1)
    write_dem(dem, z + 0.01)
    after_dem = mesh_cache.mesh_key(load_case(data))
    assert len({key, after_line, after_release, after_dem}) == 4


def test_a_spoilt_file_is_meshed_again_and_off_writes_nothing(
        tmp_path: Path, disk: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    case = load_case(outline_case(cell_size=25.0, refine=[
        {"kind": "line", "line": LINE, "size": 10.0, "distance": 60.0}]))
    calls, make = _counted()
    with gmsh_session():
        first = mesh_cache.cached_mesh(case, make)
        (path,) = disk.glob("*.npz")
        path.write_bytes(path.read_bytes()[:100])  # a truncated file
        mesh_cache.clear_memory()
        again = mesh_cache.cached_mesh(case, make)
        assert len(calls) == 2 and _same(again, first)
        mesh_cache.clear_memory()
        assert _same(mesh_cache.cached_mesh(case, make), first) and len(calls) == 2  # rewritten
        monkeypatch.setenv(mesh_cache.CACHE_ENV, "off")
        path.unlink()
        mesh_cache.clear_memory()
        mesh_cache.cached_mesh(case, make)
    assert len(calls) == 3 and not list(disk.iterdir())
    assert mesh_cache.cache_dir() is None
    monkeypatch.delenv(mesh_cache.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert mesh_cache.cache_dir() == tmp_path / "xdg" / "fem_runout" / "meshes"


def test_a_refused_outline_is_not_kept(tmp_path: Path, disk: Path) -> None:
    from fem_runout.errors import CaseError

    case = load_case(outline_case(cell_size=25.0))
    calls: list[int] = []

    def refuse(c):
        calls.append(1)
        raise CaseError("domain.outline: not meshed")

    with gmsh_session():
        for _ in range(2):
            with pytest.raises(CaseError):
                mesh_cache.cached_mesh(case, refuse)
    assert len(calls) == 2 and not disk.exists()


def test_a_run_says_where_its_mesh_came_from(tmp_path: Path, disk: Path,
                                             capsys: pytest.CaptureFixture) -> None:
    from fem_runout.api import run

    data = outline_case(cell_size=25.0, boundary="wall")
    data["time"] = {"end": 0.05}
    said = []
    for forget in (False, False, True):
        if forget:
            mesh_cache.clear_memory()
        result = run(data, write=False, quiet=False)
        said.append(next(line for line in capsys.readouterr().out.splitlines()
                         if line.startswith("mesh:")))
    cells = result.cells
    assert cells > 100
    assert said[0].startswith(f"mesh: {cells} quadrilaterals (meshed by gmsh in ")
    assert said[0].endswith(f" s; kept in {disk})")
    assert said[1:] == [f"mesh: {cells} quadrilaterals (from this process's mesh cache)",
                        f"mesh: {cells} quadrilaterals (from the mesh cache {disk})"]


def test_the_disk_keeps_the_most_recently_used_meshes(tmp_path: Path, disk: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    monkeypatch.setattr(mesh_cache, "MAX_FILES", 2)
    cases = [load_case(outline_case(cell_size=size)) for size in (40.0, 35.0, 30.0)]
    calls, make = _counted()
    with gmsh_session():
        for i, case in enumerate(cases[:2]):
            mesh_cache.cached_mesh(case, make)
            path = disk / f"{mesh_cache.mesh_key(case)}.npz"
            os.utime(path, ns=(10**18 + i, 10**18 + i))  # the first is the older
        mesh_cache.clear_memory()
        mesh_cache.cached_mesh(cases[0], make)  # read from the disk: now the newer
        mesh_cache.cached_mesh(cases[2], make)  # a third: the least recently used goes
    kept = {p.name for p in disk.glob("*.npz")}
    assert len(calls) == 3
    assert kept == {f"{mesh_cache.mesh_key(c)}.npz" for c in (cases[0], cases[2])}
