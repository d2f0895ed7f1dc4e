"""DEM input: round trip, Z at nodes, window and cell size, nodata, CRS rules."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import shapely
import yaml

from fem_runout.config import dump_resolved, load_case
from fem_runout.config.geo import DATA_ENV, data_folder
from fem_runout.errors import CaseError
from fem_runout.problem import initial_fields
from fem_runout.terrain import read_raster
from tests.terrain_helpers import (
    RES,
    X0,
    Y1,
    dem_case,
    grid_nodes,
    plane,
    write_dem,
    write_polygons,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def rel(tmp_path: Path) -> Path:
    return write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])


@pytest.mark.parametrize("suffix", [".tif", ".asc"])
def test_dem_round_trip(tmp_path: Path, suffix: str) -> None:
    z = plane()
    dem = read_raster(write_dem(tmp_path / f"dem{suffix}", z), "terrain.dem")
    # ESRI ASCII grids are read back as float32 by GDAL
    np.testing.assert_allclose(dem.values, z, rtol=0, atol=2e-5 if suffix == ".asc" else 0)
    assert dem.transform.c == X0 and dem.transform.f == Y1 and dem.res == (RES, RES)
    assert dem.crs is not None and dem.crs.to_epsg() == 31287


@pytest.mark.parametrize("suffix", [".tif", ".asc"])
def test_nodes_on_cell_centres_carry_the_raster(tmp_path: Path, rel: Path, suffix: str) -> None:
    z = plane()
    dem = write_dem(tmp_path / f"dem{suffix}", z)
    case = load_case(dem_case(dem, terrain={"crs": "EPSG:31287"}))
    assert case.domain.extent == (X0 + 2.5, X0 + 97.5, Y1 - 77.5, Y1 - 2.5)
    assert case.domain.resolved_cells == (19, 15)
    got = initial_fields(case, grid_nodes(case))["z"].reshape(16, 20)
    np.testing.assert_array_equal(got[::-1], read_raster(dem, "t").values)
    coarse = load_case(dem_case(dem, domain={"cell_size": 10.0}))
    assert coarse.domain.resolved_cells == (9, 7)
    zc = initial_fields(coarse, grid_nodes(coarse))["z"].reshape(8, 10)
    np.testing.assert_array_equal(zc[::-1], read_raster(dem, "t").values[1::2, 0:19:2])
    assert load_case(yaml.safe_load(dump_resolved(coarse))) == coarse


def test_window_snaps_to_cell_centres(tmp_path: Path, rel: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    case = load_case(dem_case(dem, domain={"window": [1001, 1061, 1930, 1999]}))
    assert case.domain.extent == (1002.5, 1057.5, 1932.5, 1997.5)
    assert case.domain.window is None and case.domain.resolved_cells == (11, 13)
    with pytest.raises(CaseError, match="domain.window"):
        load_case(dem_case(dem, domain={"window": [0, 10, 0, 10]}))


def _cli(tmp_path: Path, data: dict) -> subprocess.CompletedProcess:
    path = tmp_path / "case.yaml"
    data = {**data, "output": {**data.get("output", {}), "dir": str(tmp_path / "out")}}
    path.write_text(yaml.safe_dump(data))
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "fem_runout", str(path)], capture_output=True,
                          text=True, timeout=120, env=env, cwd=ROOT)


def test_nodata_is_an_error_or_filled(tmp_path: Path, rel: Path) -> None:
    z = plane()
    z[5:8, 12:15] = np.nan
    dem = write_dem(tmp_path / "dem.tif", z)
    proc = _cli(tmp_path, dem_case(dem))
    assert proc.returncode == 2, proc.stderr
    assert "terrain.dem: 9 nodes of the domain fall on nodata" in proc.stderr
    assert "terrain.fill_nodata" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()
    case = load_case(dem_case(dem, terrain={"fill_nodata": True}))
    filled = initial_fields(case, grid_nodes(case))["z"].reshape(16, 20)[::-1]
    assert np.isfinite(filled).all()
    assert z[6, 11] > filled[6, 13] > z[6, 15]  # interpolated between valid cells
    inside = load_case(dem_case(dem, domain={"window": [1000, 1050, 1950, 2000]}))
    assert inside.domain.extent == (1002.5, 1047.5, 1952.5, 1997.5)


def test_crs_mismatch_is_exit_2(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)],
                   crs="EPSG:32633")
    proc = _cli(tmp_path, dem_case(dem))
    assert proc.returncode == 2, proc.stderr
    assert "initial.release[0].polygon: its CRS EPSG:32633 differs from the DEM's EPSG:31287" \
        in proc.stderr
    assert not (tmp_path / "out").exists()
    with pytest.raises(CaseError, match="terrain.crs: EPSG:4326 differs from the CRS of the DEM"):
        load_case(dem_case(dem, terrain={"crs": "EPSG:4326"}))


def test_dem_without_crs(tmp_path: Path, rel: Path) -> None:
    dem = write_dem(tmp_path / "dem.asc", plane(), crs=None)
    assert read_raster(dem, "t").crs is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        given = load_case(dem_case(dem, terrain={"crs": "EPSG:31287"}))
    assert given.terrain.crs == "EPSG:31287"
    with pytest.warns(UserWarning, match="has no CRS; using EPSG:31287 of initial.release"):
        taken = load_case(dem_case(dem))
    assert taken.terrain.crs == "EPSG:31287"


def test_missing_dem_and_data_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DATA_ENV, str(tmp_path))
    assert data_folder() == tmp_path
    data = dem_case(Path("${FEM_RUNOUT_DATA}/nowhere/dem.asc"),
                    release={"polygon": "${FEM_RUNOUT_DATA}/nowhere/rel.shp", "thickness": 1})
    with pytest.raises(CaseError, match=f"terrain.dem: file '{tmp_path}/nowhere/dem.asc' does "
                                        "not exist; FEM_RUNOUT_DATA names the data folder") as err:
        load_case(data)
    assert "github.com/avaframe/AvaFrame" in str(err.value)
    monkeypatch.delenv(DATA_ENV)
    assert data_folder() == (ROOT.parent / "shared" / "data").resolve()


def test_schema_rules(tmp_path: Path, rel: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    with pytest.raises(CaseError, match="terrain.elevation: give either elevation or dem"):
        load_case(dem_case(dem, terrain={"elevation": "x"}))
    with pytest.raises(CaseError, match="domain.extent: required key is missing .or give terr"):
        load_case({"name": "a", "domain": {"cells": [1, 1], "window": [0, 1, 0, 1]},
                   "initial": {"depth": "1"}, "time": {"end": 1}})
    with pytest.raises(CaseError, match="time.max: required with end: auto"):
        load_case(dem_case(dem, time={"end": "auto", "max": None}))
    with pytest.raises(CaseError, match="initial: give exactly one of depth, free_surface or"):
        load_case(dem_case(dem, initial={"depth": "1"}))


AVAKOT = data_folder() / "avaKot"


@pytest.mark.skipif(not AVAKOT.is_dir(), reason="avaKot data not found (FEM_RUNOUT_DATA)")
def test_avakot_case() -> None:
    case = load_case(ROOT / "cases" / "avakot.yaml")
    nx, ny = case.domain.resolved_cells
    assert (nx, ny) == (219, 258) and 5.5e4 < (nx + 1) * (ny + 1) < 6.5e4
    assert case.terrain.crs == "EPSG:31287"
    dem = read_raster(case.resolve_input(case.terrain.dem), "t", True)
    xc, yc = dem.centres()
    step = dem.res[0]
    assert case.domain.extent == (xc[0], xc[0] + 438 * step, yc[-1], yc[-1] + 516 * step)
    x, y = np.meshgrid(np.linspace(*case.domain.extent[:2], nx + 1),
                       np.linspace(*case.domain.extent[2:], ny + 1))
    h = case.initial_depth(x, y)
    area = np.full((ny + 1, nx + 1), case.domain.cell_size**2)
    # the 1.0 m is normal to the slope (thickness_normal): times cos(slope) it is the polygon
    # area x 1.0 m; the volume is com1DFA 2.1's for the same polygon (21 346 m³) within 2 %
    from fem_runout.terrain.nodes import inv_cos_slope

    normal = h / inv_cos_slope(case, x, y)
    assert (normal * area).sum() == pytest.approx(15188.05685224, rel=1e-9)
    assert (h * area).sum() == pytest.approx(21346.32, rel=0.02)
