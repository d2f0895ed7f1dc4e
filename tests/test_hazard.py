"""Hazard rasters on the DEM grid, the run summary and the volume balance with outflow."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
import shapely

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.output.hazard import MAP_NAMES, NODATA
from tests.terrain_helpers import dem_case, plane, write_dem, write_polygons


@pytest.fixture(scope="module")
def steep_run(tmp_path_factory):
    """A release sliding off a steep synthetic DEM through the open right side (1 rank)."""
    tmp = tmp_path_factory.mktemp("steep")
    dem = write_dem(tmp / "dem.tif", plane(slope=0.6))
    write_polygons(tmp / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    case = load_case(dem_case(
        dem, output={"dir": str(tmp / "out"), "ascii": True, "pictures": True},
        material={"friction": {"law": "voellmy", "mu": 0.1, "xi": 1000}},
        time={"end": "auto", "max": 12.0}))
    return case, run(case, overwrite=True), dem


def test_rasters_match_the_dem_grid(steep_run) -> None:
    _, result, dem = steep_run
    with rasterio.open(dem) as src:
        shape, transform, crs = src.shape, src.transform, src.crs
    for name in MAP_NAMES:
        for suffix in (".tif", ".asc"):
            with rasterio.open(result.out_dir / f"{name}{suffix}") as out:
                assert out.shape == shape and out.transform.almost_equals(transform)
                if suffix == ".tif":
                    assert out.crs == crs and out.nodata == NODATA
    with rasterio.open(result.out_dir / "deposit_depth.tif") as out:
        deposit = out.read(1)
    np.testing.assert_array_equal(deposit, result.h.reshape(16, 20)[::-1])
    with rasterio.open(result.out_dir / "arrival_time.tif") as out:
        arrival = out.read(1)[::-1].ravel()
    h0_nodes = arrival == 0.0
    assert h0_nodes.sum() > 0 and np.all(arrival[~h0_nodes & (arrival != NODATA)] > 0)
    for png in ("hazard_map.png", "deposit_3d.png"):
        assert (result.out_dir / png).stat().st_size > 10_000


def test_volume_balance_with_outflow(steep_run) -> None:
    _, result, _ = steep_run
    s = result.summary
    assert s["released_volume"] == pytest.approx(20 * 25 * 1.0, rel=1e-12)
    assert s["outflow_volume"] > 0.1 * s["released_volume"]  # a good part left the domain
    assert s["dried_volume"] >= 0.0  # films thinner than the dry tolerance
    balance = s["deposit_volume"] + s["outflow_volume"] + s["dried_volume"] - s["released_volume"]
    assert abs(balance) <= 1e-10 * s["released_volume"]
    saved = json.loads((result.out_dir / "summary.json").read_text())
    assert saved["deposit_volume"] == s["deposit_volume"] and saved["ranks"] == 1
    assert s["runout_length"] > 40 and 0 < s["travel_angle_deg"] < 35
    assert s["peak_pressure_max"] == pytest.approx(200 * s["peak_speed_max"] ** 2, rel=1e-12)


def test_coarser_mesh_and_no_dem(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    case = load_case(dem_case(dem, domain={"cell_size": 10.0},
                              output={"dir": str(tmp_path / "coarse")}, time={"max": 1.0}))
    result = run(case)
    with rasterio.open(result.out_dir / "peak_depth.tif") as out:
        peak = out.read(1)
        assert out.shape == (16, 20)
    nodes = result.peak_depth.reshape(8, 10)[::-1]
    np.testing.assert_allclose(peak[1::2, 0:19:2], nodes, rtol=1e-12)  # on the nodes
    assert (peak[:, 19] == NODATA).all()  # the last column lies outside the domain
    with rasterio.open(result.out_dir / "arrival_time.tif") as out:
        arrival = out.read(1)
    wet = peak > case.output.front_threshold
    assert wet.sum() > wet[1::2, 0:19:2].sum()  # wet pixels between the nodes too
    assert (arrival[wet] != NODATA).all() and arrival[wet].min() == 0.0
    assert arrival[wet].max() <= 1.0 + 1e-12
    flat = {"name": "flat", "domain": {"extent": [0, 4, 0, 2], "cells": [4, 2]},
            "initial": {"depth": "where(x < 2, 1, 0)"}, "time": {"end": 0.2},
            "output": {"dir": str(tmp_path / "flat"), "pictures": False}}
    result = run(load_case(flat))
    with rasterio.open(result.out_dir / "peak_depth.tif") as out:
        assert out.shape == (3, 5) and out.crs is None and out.transform.a == 1.0
        assert out.bounds == (-0.5, -0.5, 4.5, 2.5)
        np.testing.assert_array_equal(out.read(1), result.peak_depth.reshape(3, 5)[::-1])


def test_areas_are_counted_on_the_dem_pixels(tmp_path: Path) -> None:
    """With a DEM the summary's areas are the GeoTIFFs' pixels above the threshold.

    The same with and without written outputs, and on a mesh coarser than the DEM (10 m
    nodes, 5 m pixels), where counting nodes would weight each by its 100 m² dual cell.
    """
    dem = write_dem(tmp_path / "dem.tif", plane())
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    spec = dem_case(dem, domain={"cell_size": 10.0}, output={"dir": str(tmp_path / "out")},
                    time={"max": 2.0})
    case = load_case(spec)
    written = run(case)
    threshold = case.output.front_threshold
    areas = {}
    for name, key in (("peak_depth", "affected_area"), ("deposit_depth", "deposit_area")):
        with rasterio.open(written.out_dir / f"{name}.tif") as out:
            pixels = out.read(1)
            areas[key] = np.count_nonzero(pixels > threshold) * abs(out.res[0] * out.res[1])
        assert written.summary[key] == pytest.approx(areas[key], rel=1e-12), key
    assert areas["affected_area"] >= areas["deposit_area"] > 0
    unwritten = run(case, write=False)
    for key in ("affected_area", "deposit_area", "runout_length"):
        assert unwritten.summary[key] == written.summary[key], key


def test_areas_on_a_gmsh_mesh_are_the_pixels(tmp_path: Path) -> None:
    """The same measure on an unstructured mesh (outline inside the DEM, irregular cells)."""
    dem = write_dem(tmp_path / "dem.tif", plane())
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    outline = [[1003, 1923], [1097, 1923], [1097, 1997], [1003, 1997]]
    case = load_case(dem_case(dem, domain={"outline": outline, "cell_size": 8.0},
                              output={"dir": str(tmp_path / "out")}, time={"max": 2.0}))
    written = run(case)
    with rasterio.open(written.out_dir / "peak_depth.tif") as out:
        pixels, res = out.read(1), out.res
    assert (pixels == NODATA).any()  # outside the outline
    area = np.count_nonzero(pixels > case.output.front_threshold) * abs(res[0] * res[1])
    assert written.summary["affected_area"] == pytest.approx(area, rel=1e-12) and area > 0
    unwritten = run(case, write=False)
    assert unwritten.summary["affected_area"] == written.summary["affected_area"]


def test_dampm_volume_balance_with_outflow(tmp_path: Path) -> None:
    """DAMPM on the steep DEM: particle volume + outflow is the released volume to round-off."""
    from mpi4py import MPI

    from fem_runout.api import build_solver
    from fem_runout.runner import Runner, Schedule

    dem = write_dem(tmp_path / "dem.tif", plane(slope=0.6))
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    case = load_case(dem_case(
        dem, method="mpm", output={"dir": str(tmp_path / "out"), "pictures": False},
        material={"friction": {"law": "voellmy", "mu": 0.1, "xi": 1000}},
        time={"end": "auto", "max": 12.0}))
    result = run(case, overwrite=True)
    s = result.summary
    assert s["released_volume"] == pytest.approx(20 * 25 * 1.0, rel=1e-12)
    assert s["outflow_volume"] > 0.1 * s["released_volume"]
    balance = s["deposit_volume"] + s["outflow_volume"] - s["released_volume"]
    assert abs(balance) <= 1e-12 * s["released_volume"]
    assert (result.out_dir / "deposit_depth.tif").is_file() and s["particles"] > 0
    solver = build_solver(case, MPI.COMM_SELF)
    start = solver.particle_volume()
    Runner(solver, Schedule(12.0, 0.9, 12.0), []).run()
    assert solver.outflow_volume > 0.1 * start
    assert abs(solver.particle_volume() + solver.outflow_volume - start) <= 1e-14 * start


def test_slope_normal_peak_depth_map(steep_run) -> None:
    """``peak_depth_normal`` = peak vertical depth × cos(slope), and each map says what it is."""
    _, result, _ = steep_run
    with rasterio.open(result.out_dir / "peak_depth.tif") as a, \
            rasterio.open(result.out_dir / "peak_depth_normal.tif") as b:
        vertical, normal = a.read(1), b.read(1)
        assert "vertical" in a.descriptions[0] and "normal" in b.descriptions[0]
    wet = vertical > 0
    assert wet.sum() > 10
    ratio = normal[wet] / vertical[wet]  # cos of the plane (slope 0.6), less on the bump
    plane_cos = 1 / np.sqrt(1 + 0.6**2)
    assert ratio.max() <= 1.0 and ratio.min() >= 0.9 * plane_cos
    assert np.median(ratio) == pytest.approx(plane_cos, rel=0.01)
    assert result.summary["peak_depth_normal_max"] <= result.summary["peak_depth_max"]


def test_arrival_time_is_the_mean_over_the_reached_nodes():
    """Q1 samples of t_i 1_i and 1_i: the reached nodes' times, renormalised; NaN if none."""
    from fem_runout.output.hazard import arrival_over_reached

    # a pixel a quarter of the way from a node reached at 2 s to one never reached
    got = arrival_over_reached(np.array([0.75 * 2.0, 0.5 * 2.0 + 0.5 * 4.0, 0.0]),
                               np.array([0.75, 1.0, 0.0]))
    assert got[0] == 2.0 and got[1] == 3.0 and np.isnan(got[2])
