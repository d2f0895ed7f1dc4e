"""Elevation and release depth at arbitrary nodes, from the case (DEM or expressions)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.terrain.dem import read_raster, sample_raster
from fem_runout.terrain.release import feature_thickness, polygon_depth, read_polygons

if TYPE_CHECKING:  # fem_runout.config imports this package (lazily): no import back
    from fem_runout.config import Case

__all__ = ["elevation_at", "initial_depth_at", "inv_cos_slope", "release_depth"]


def elevation_at(case: Case, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Terrain elevation [m] at points: the DEM (bilinear on cell centres) or the expression.

    Raises:
        CaseError: If a point depends on a nodata cell of the DEM.
    """
    t = case.terrain
    if t.dem is None:
        return np.asarray(t.elevation_fn()(x, y), dtype=np.float64) + 0.0 * np.asarray(x)
    raster = read_raster(case.resolve_input(t.dem), "terrain.dem", t.fill_nodata)
    z = sample_raster(raster, np.asarray(x), np.asarray(y))
    bad = np.isnan(z)
    if bad.any():
        i = int(np.flatnonzero(bad.ravel())[0])
        raise CaseError(
            f"terrain.dem: {int(bad.sum())} nodes of the domain fall on nodata cells of "
            f"'{raster.path.name}' (e.g. x={np.ravel(x)[i]:.6g}, y={np.ravel(y)[i]:.6g}); set "
            "terrain.fill_nodata: true or choose a domain.window inside the data"
        )
    return z


def _secant(case: Case) -> tuple[float, float]:
    """Grid spacing ``(dx, dy)`` of the case's mesh."""
    xmin, xmax, ymin, ymax = case.domain.extent or (0.0, 1.0, 0.0, 1.0)
    nx, ny = case.domain.resolved_cells
    return (xmax - xmin) / nx, (ymax - ymin) / ny


def inv_cos_slope(case: Case, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``1 / cos(slope) = sqrt(1 + |grad z|²)`` by centred differences over one cell.

    Turns a thickness normal to the slope into a vertical depth (``thickness_normal``).
    """
    dx, dy = _secant(case)
    zx = (elevation_at(case, x + dx / 2, y) - elevation_at(case, x - dx / 2, y)) / dx
    zy = (elevation_at(case, x, y + dy / 2) - elevation_at(case, x, y - dy / 2)) / dy
    return np.sqrt(1.0 + zx**2 + zy**2)


def release_depth(case: Case, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Vertical depth [m] at nodes from ``initial.release`` (areas add up where they overlap).

    Raises:
        CaseError: For unreadable files, a missing thickness or a negative thickness raster.
    """
    assert case.initial.release is not None and case.domain.extent is not None
    h = np.zeros(np.shape(x))
    for i, item in enumerate(case.initial.release):
        key = f"initial.release[{i}]"
        if item.raster is not None:
            raster = read_raster(case.resolve_input(item.raster), f"{key}.raster")
            t = np.nan_to_num(sample_raster(raster, x, y), nan=0.0)
            if (t < 0).any():
                raise CaseError(f"{key}.raster: thickness must be >= 0, min is {t.min():g}")
        else:
            assert item.polygon is not None
            polys = read_polygons(case.resolve_input(item.polygon), f"{key}.polygon")
            thickness = feature_thickness(polys, item.thickness, key)
            t = polygon_depth(polys, thickness, x, y, _secant(case), case.domain.extent)
        if item.thickness_normal:
            t = t * inv_cos_slope(case, x, y)
        h += t
    return h


def initial_depth_at(case: Case, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """Release depth when the case has ``initial.release``, else None (expressions apply)."""
    if case.initial.release is None:
        return None
    return release_depth(case, x, y)
