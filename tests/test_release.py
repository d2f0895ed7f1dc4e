"""Release areas: volume of a polygon release, several areas, attribute thickness, slope-normal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from mpi4py import MPI

from fem_runout.config import load_case
from fem_runout.errors import CaseError
from fem_runout.problem import initial_fields
from fem_runout.tg2.solver import build_tg2
from tests.terrain_helpers import RES, dem_case, grid_nodes, plane, write_dem, write_polygons

TRIANGLE = shapely.Polygon([(1012.3, 1941.1), (1071.7, 1952.9), (1033.3, 1988.2)])
RING = shapely.Point(1060, 1960).buffer(12.0).difference(shapely.Point(1060, 1960).buffer(5.0))


def _volume(case) -> float:
    solver = build_tg2(case, MPI.COMM_SELF)
    return float(solver.lumped_mass @ solver.fields["h"].x.array)


@pytest.mark.parametrize("cell_size", [5.0, 10.0, 7.3])
def test_polygon_volume_is_area_times_thickness(tmp_path: Path, cell_size: float) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    poly = write_polygons(tmp_path / "tri.shp", [TRIANGLE])
    case = load_case(dem_case(dem, {"polygon": str(poly), "thickness": 1.5},
                              domain={"cell_size": cell_size}))
    volume = _volume(case)
    exact = TRIANGLE.area * 1.5
    assert abs(volume - exact) <= 1e-9 * exact  # far inside one cell's area x thickness
    assert abs(volume - exact) < cell_size**2 * 1.5


def test_several_areas_and_attribute_thickness(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    two = write_polygons(tmp_path / "two.geojson", [TRIANGLE, RING], thickness=[0.5, 2.0])
    ring = write_polygons(tmp_path / "ring.geojson", [RING])
    case = load_case(dem_case(dem, [{"polygon": str(two)}, {"polygon": str(ring),
                                                            "thickness": 0.25}]))
    expected = 0.5 * TRIANGLE.area + 2.0 * RING.area + 0.25 * RING.area
    assert _volume(case) == pytest.approx(expected, rel=1e-10)
    with pytest.raises(CaseError, match=r"initial.release\[0\].thickness: required key is "
                                        r"missing \(the features of 'ring.geojson' have no"):
        load_case(dem_case(dem, {"polygon": str(ring)}))


def test_thickness_normal_to_the_slope(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane(slope=0.75, bump=0.0))  # 1/cos = 1.25
    poly = write_polygons(tmp_path / "box.geojson", [shapely.box(1000, 1900, 1100, 2000)])
    vertical = load_case(dem_case(dem, {"polygon": str(poly), "thickness": 2.0}))
    normal = load_case(dem_case(dem, {"polygon": str(poly), "thickness": 2.0,
                                      "thickness_normal": True}))
    hv = initial_fields(vertical, grid_nodes(vertical))["h"].reshape(16, 20)
    hn = initial_fields(normal, grid_nodes(normal))["h"].reshape(16, 20)
    np.testing.assert_allclose(hv, 2.0, rtol=1e-12)
    far = (slice(1, 15), slice(1, 19))  # inside: centred slopes
    np.testing.assert_allclose(hn[far], 2.0 * 1.25, rtol=1e-9)


def test_raster_release(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "dem.tif", plane())
    thickness = np.zeros((16, 20))
    thickness[2:5, 3:7] = 1.2
    rel = write_dem(tmp_path / "thick.asc", thickness, crs=None)
    case = load_case(dem_case(dem, {"raster": str(rel)}))
    h = initial_fields(case, grid_nodes(case))["h"].reshape(16, 20)[::-1]
    np.testing.assert_allclose(h, thickness, atol=1e-6)
    assert _volume(case) == pytest.approx(1.2 * 12 * RES**2, rel=1e-6)
