"""Rasters (GeoTIFF, ESRI ASCII) read with rasterio, and bilinear sampling at points.

Values are sampled at DEM *cell centres*: a point on a cell centre gets exactly that cell's
value, so Q1 nodes placed on cell centres carry the raster values unchanged.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.errors import CaseError

__all__ = ["Raster", "read_raster", "sample_grid", "sample_raster"]

# Fractional indices within this of an integer are snapped to it (round-off of node coordinates).
_SNAP = 1e-6


@dataclass(frozen=True, eq=False)
class Raster:
    """A north-up raster band.

    Attributes:
        values: (rows, cols) float64 values, NaN where nodata; row 0 is the northern edge.
        transform: The rasterio affine transform (pixel corner to map coordinates).
        crs: The coordinate reference system (rasterio ``CRS``) or None.
        path: The file it came from.
    """

    values: np.ndarray
    transform: Any
    crs: Any
    path: Path

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return self.values.shape  # type: ignore[return-value]

    @property
    def res(self) -> tuple[float, float]:
        """Pixel size ``(dx, dy)`` [m], both positive."""
        return float(self.transform.a), float(-self.transform.e)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre x of every column and y of every row (y decreasing)."""
        t = self.transform
        rows, cols = self.shape
        return t.c + t.a * (np.arange(cols) + 0.5), t.f + t.e * (np.arange(rows) + 0.5)

    def centre_extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the cell centres."""
        xc, yc = self.centres()
        return float(xc[0]), float(xc[-1]), float(yc[-1]), float(yc[0])


def read_raster(path: str | Path, key: str, fill_nodata: bool = False) -> Raster:
    """Read band 1 of a raster (cached by path, modification time and ``fill_nodata``).

    Args:
        path: GeoTIFF, ESRI ASCII grid or any raster GDAL reads.
        key: Case key named in error messages (``terrain.dem``).
        fill_nodata: Fill nodata cells by inverse-distance interpolation (GDAL FillNodata).

    Raises:
        CaseError: If the file is missing or unreadable, or the raster is rotated.
    """
    p = Path(path)
    if not p.is_file():
        raise CaseError(f"{key}: file '{p}' does not exist")
    return _read_cached(str(p.resolve()), p.stat().st_mtime_ns, key, fill_nodata)


@functools.lru_cache(maxsize=8)
def _read_cached(path: str, mtime: int, key: str, fill_nodata: bool) -> Raster:
    import rasterio
    from rasterio.errors import RasterioError

    try:
        with rasterio.open(path) as src:
            band = src.read(1, masked=True)
            transform, crs = src.transform, src.crs
    except (RasterioError, OSError, ValueError) as exc:
        raise CaseError(f"{key}: cannot read raster '{path}': {exc}") from None
    if transform.b != 0 or transform.d != 0 or transform.a <= 0 or transform.e >= 0:
        raise CaseError(f"{key}: '{path}' is not a north-up raster (rotated or flipped)")
    values = np.ma.filled(band.astype(np.float64), np.nan)
    values[~np.isfinite(values)] = np.nan
    if fill_nodata and np.isnan(values).any() and not np.isnan(values).all():
        values = _fill(values)
    values.setflags(write=False)
    return Raster(values, transform, crs, Path(path))


def _fill(values: np.ndarray) -> np.ndarray:
    """Fill NaN cells by GDAL's inverse-distance interpolation from the valid ones."""
    from rasterio.fill import fillnodata

    mask = np.isfinite(values).astype(np.uint8)
    reach = float(np.hypot(*values.shape)) + 1.0
    filled = fillnodata(np.where(mask, values, 0.0), mask=mask, max_search_distance=reach,
                        smoothing_iterations=0)
    return np.asarray(filled, dtype=np.float64)


def _weights(pos: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower index and weight of the upper neighbour for fractional positions ``pos``."""
    near = np.round(pos)
    pos = np.where(np.abs(pos - near) < _SNAP, near, pos)
    pos = np.clip(pos, 0.0, n - 1.0)
    i0 = np.minimum(np.floor(pos).astype(np.int64), max(n - 2, 0))
    return i0, pos - i0


def sample_grid(
    values: np.ndarray, x0: float, dx: float, y0: float, dy: float, x: np.ndarray,
    y: np.ndarray, method: str = "bilinear",
) -> np.ndarray:
    """Sample a regular grid of point values at ``(x, y)`` (clamped at the edges).

    Args:
        values: (rows, cols) values at ``(x0 + j dx, y0 + i dy)``; ``dy`` may be negative.
        x0: x of column 0.
        dx: Column spacing.
        y0: y of row 0.
        dy: Row spacing.
        x: Query x.
        y: Query y.
        method: ``bilinear`` (NaN if a used neighbour is NaN) or ``nearest``.

    Returns:
        The sampled values, shape of ``x``.
    """
    rows, cols = values.shape
    fc, fr = (np.asarray(x) - x0) / dx, (np.asarray(y) - y0) / dy
    if method == "nearest":
        c = np.clip(np.round(fc).astype(np.int64), 0, cols - 1)
        r = np.clip(np.round(fr).astype(np.int64), 0, rows - 1)
        return values[r, c]
    c0, wc = _weights(fc, cols)
    r0, wr = _weights(fr, rows)
    c1, r1 = np.minimum(c0 + 1, cols - 1), np.minimum(r0 + 1, rows - 1)
    out = np.zeros(np.shape(fc))
    for r, c, w in ((r0, c0, (1 - wr) * (1 - wc)), (r0, c1, (1 - wr) * wc),
                    (r1, c0, wr * (1 - wc)), (r1, c1, wr * wc)):
        v = values[r, c]
        out += np.where(w == 0.0, 0.0, w * np.where(w == 0.0, 0.0, v))
        out[(w != 0.0) & np.isnan(v)] = np.nan
    return out


def sample_raster(raster: Raster, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear value of a raster at points, with cell-centre values as the grid values.

    Points outside the cell-centre extent take the nearest edge value; NaN marks points whose
    value depends on a nodata cell.
    """
    xc, yc = raster.centres()
    dx, dy = raster.res
    return sample_grid(raster.values, float(xc[0]), dx, float(yc[0]), -dy, x, y)
