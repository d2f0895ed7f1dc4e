"""Case keys for real terrain: the DEM (``terrain``) and the release areas (``initial.release``).

These models only check the case text; the files are opened by
:func:`fem_runout.terrain.resolve.resolve_terrain` when the case is loaded. The data folder
(``${FEM_RUNOUT_DATA}``) lives in :mod:`fem_runout.terrain.paths` and is re-exported here.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BeforeValidator, Field, model_validator

from fem_runout.config.expr import Expression, compile_expression
from fem_runout.config.types import Bool, Expr, Real, SpecError, StrictSpec, is_number
from fem_runout.terrain.paths import DATA_ENV, DATA_PLACEHOLDER, data_folder, expand_data_path

__all__ = [
    "DATA_ENV",
    "DATA_PLACEHOLDER",
    "ReleaseArea",
    "TerrainSpec",
    "data_folder",
    "expand_data_path",
    "parse_release",
    "parse_window",
]


def _path(value: Any) -> Any:
    if value is None:
        return value
    if not isinstance(value, str) or not value.strip():
        raise SpecError(f"must be a file path, got {value!r}")
    return value


FilePath = Annotated[str, BeforeValidator(_path)]


class TerrainSpec(StrictSpec):
    """Terrain elevation ``z(x, y)`` [m]: an expression, or a DEM raster.

    Attributes:
        elevation: Elevation expression (used when ``dem`` is not given).
        dem: GeoTIFF or ESRI ASCII raster of the elevation (relative to the case file;
            ``${FEM_RUNOUT_DATA}`` expands to the data folder).
        fill_nodata: Fill nodata cells inside the domain by inverse-distance interpolation
            instead of refusing them.
        crs: Coordinate reference system of the DEM (``EPSG:31287``...), for a DEM without one;
            filled from the DEM when the case is loaded.
    """

    elevation: Expr = "0"
    dem: FilePath | None = None
    fill_nodata: Bool = False
    crs: str | None = None

    @model_validator(mode="after")
    def _dem_or_expression(self) -> TerrainSpec:
        if self.dem is None:
            if self.fill_nodata or self.crs is not None:
                raise SpecError("only used with terrain.dem", "fill_nodata" if self.fill_nodata
                                else "crs")
        elif self.elevation != "0":
            raise SpecError("give either elevation or dem, not both", "elevation")
        return self

    def elevation_fn(self) -> Expression:
        """Return the compiled elevation expression."""
        return compile_expression(self.elevation, "terrain.elevation")


class ReleaseArea(StrictSpec):
    """One release area: polygons with a thickness, or a thickness raster.

    Attributes:
        polygon: Shapefile or GeoJSON with polygon features.
        raster: Raster of the release thickness [m] (instead of ``polygon``).
        thickness: Release thickness [m]; default: each feature's ``thickness`` attribute.
        thickness_normal: The thickness is measured normal to the slope (the vertical depth
            is ``thickness / cos(slope)``); default: vertical.
    """

    polygon: FilePath | None = None
    raster: FilePath | None = None
    thickness: Real | None = Field(None, gt=0)
    thickness_normal: Bool = False

    @model_validator(mode="after")
    def _one_source(self) -> ReleaseArea:
        if (self.polygon is None) == (self.raster is None):
            raise SpecError("give exactly one of polygon: <file> or raster: <file>")
        if self.raster is not None and self.thickness is not None:
            raise SpecError("not used with raster (the raster holds the thickness)", "thickness")
        return self


def parse_release(value: Any) -> Any:
    """Accept one release mapping or a list of them; return a tuple."""
    if value is None:
        return value
    items = [value] if isinstance(value, dict) else value
    if not isinstance(items, list | tuple) or not items:
        raise SpecError(
            "must be {polygon: <file>, thickness: <m>}, {raster: <file>} or a list of those"
        )
    return tuple(items)


def parse_window(value: Any) -> Any:
    """Check ``[xmin, xmax, ymin, ymax]``."""
    if value is None:
        return value
    ok = isinstance(value, list | tuple) and len(value) == 4 and all(map(is_number, value))
    if not ok or not all(math.isfinite(v) for v in value):
        raise SpecError(f"must be four numbers [xmin, xmax, ymin, ymax], got {value!r}")
    if not (value[0] < value[1] and value[2] < value[3]):
        raise SpecError(f"must have xmin < xmax and ymin < ymax, got {list(value)!r}")
    return tuple(float(v) for v in value)
