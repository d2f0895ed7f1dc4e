"""The half-pixel DEM shift of ``python -m fem_runout.bench dem-sampling``."""

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from fem_runout.bench.dem_sampling import half_pixel_shift, write_shifted
from fem_runout.terrain.dem import read_raster


def test_a_plane_moves_by_half_a_pixel_east_and_south():
    rows, cols = np.mgrid[0:6, 0:8].astype(float)
    plane = 3.0 + 0.5 * cols - 0.25 * rows  # z = 3 + 0.5 c - 0.25 r at pixel (r, c)
    shifted = half_pixel_shift(plane)
    # bilinear at (r + 1/2, c + 1/2): exact for a plane, except the repeated last row/column
    np.testing.assert_allclose(shifted[:-1, :-1], (plane + 0.25 - 0.125)[:-1, :-1],
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(shifted[-1, :-1], (plane + 0.25)[-1, :-1], rtol=0, atol=1e-14)
    assert shifted.shape == plane.shape


@pytest.mark.parametrize("rows, cols", [(1, 1), (1, -1), (-1, 1), (-1, -1)])
def test_each_diagonal_samples_the_plane_half_a_pixel_away(rows, cols):
    r, c = np.mgrid[0:6, 0:8].astype(float)
    plane = 3.0 + 0.5 * c - 0.25 * r
    shifted = half_pixel_shift(plane, rows, cols)
    inner = (slice(1, -1), slice(1, -1))  # (the edges repeat a row or column)
    np.testing.assert_allclose(shifted[inner], (plane + 0.25 * cols - 0.125 * rows)[inner],
                               rtol=0, atol=1e-14)


def test_nodata_spreads_to_the_pixels_that_sample_it():
    values = np.arange(20.0).reshape(4, 5)
    values[2, 3] = np.nan
    nan = np.isnan(half_pixel_shift(values))
    assert set(zip(*np.nonzero(nan), strict=True)) == {(1, 2), (1, 3), (2, 2), (2, 3)}


def test_the_shifted_dem_keeps_the_grid(tmp_path):
    dem = tmp_path / "dem.tif"
    values = np.random.default_rng(2).normal(1000.0, 5.0, (7, 9))
    profile = {"driver": "GTiff", "height": 7, "width": 9, "count": 1, "dtype": "float64",
               "transform": from_origin(1000.0, 2000.0, 5.0, 5.0), "crs": "EPSG:31287"}
    with rasterio.open(dem, "w", **profile) as dst:
        dst.write(values, 1)
    out = read_raster(write_shifted(dem, tmp_path / "out" / "shifted.tif"), "t")
    assert out.transform == profile["transform"] and out.crs.to_epsg() == 31287
    np.testing.assert_array_equal(out.values, half_pixel_shift(values))
