"""Synthetic DEMs and release polygons written with rasterio / pyogrio, for the terrain tests."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

X0, Y1, RES = 1000.0, 2000.0, 5.0  # west edge, north edge, pixel size [m]


def plane(rows: int = 16, cols: int = 20, slope: float = 0.3, bump: float = 2.0) -> np.ndarray:
    """Elevation of a plane falling towards +x plus a small bump (row 0 is the north)."""
    xc = X0 + RES * (np.arange(cols) + 0.5)
    yc = Y1 - RES * (np.arange(rows) + 0.5)
    x, y = np.meshgrid(xc, yc)
    return 100.0 - slope * (x - X0) + bump * np.exp(-((x - 1040) ** 2 + (y - 1960) ** 2) / 200)


def write_dem(path: Path, z: np.ndarray, crs: str | None = "EPSG:31287",
              nodata: float = -9999.0) -> Path:
    """Write ``z`` as a GeoTIFF or ESRI ASCII grid (by suffix); NaN becomes nodata."""
    import rasterio
    from rasterio.transform import from_origin

    driver = "AAIGrid" if path.suffix == ".asc" else "GTiff"
    values = np.where(np.isnan(z), nodata, z)
    with rasterio.open(path, "w", driver=driver, height=z.shape[0], width=z.shape[1], count=1,
                       dtype="float64", crs=crs, transform=from_origin(X0, Y1, RES, RES),
                       nodata=nodata) as dst:
        dst.write(values, 1)
    prj = path.with_suffix(".prj")
    if crs is None and prj.exists():
        prj.unlink()
    return path


def write_polygons(path: Path, polygons: list[Any], crs: str | None = "EPSG:31287",
                   thickness: list[float] | None = None) -> Path:
    """Write shapely polygons to a GeoJSON/Shapefile (optional ``thickness`` attribute)."""
    import pyogrio
    import shapely

    wkb = np.array([shapely.to_wkb(p) for p in polygons], dtype=object)
    fields, names = [], []
    if thickness is not None:
        fields.append(np.asarray(thickness, dtype=np.float64))
        names.append("thickness")
    pyogrio.raw.write(str(path), wkb, fields, names, geometry_type="Polygon", crs=crs,
                      driver="GeoJSON" if path.suffix == ".geojson" else "ESRI Shapefile")
    return path


def dem_case(dem: Path, release: Any = None, **sections: Any) -> dict[str, Any]:
    """A case mapping on ``dem`` (default: a 1 m square release near the top of the plane)."""
    data: dict[str, Any] = {
        "name": "synthetic",
        "domain": {"boundary": "open"},
        "terrain": {"dem": str(dem)},
        "initial": {"release": release or {"polygon": str(dem.parent / "rel.geojson"),
                                           "thickness": 1.0}},
        "material": {"density": 200, "friction": {"law": "voellmy", "mu": 0.2, "xi": 1000}},
        "time": {"end": "auto", "max": 30, "dt_max": 0.2},
        "output": {"pictures": False, "front_threshold": 0.01},
        "numerics": {"thin_depth": 0.01},
    }
    for key, value in sections.items():
        data[key] = {**data.get(key, {}), **value} if isinstance(value, dict) else value
    return data


def grid_nodes(case: Any) -> np.ndarray:
    """Node coordinates of the case's structured mesh, rows of increasing y."""
    xmin, xmax, ymin, ymax = case.domain.extent
    nx, ny = case.domain.resolved_cells
    x, y = np.meshgrid(np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1))
    return np.column_stack([x.ravel(), y.ravel()])
