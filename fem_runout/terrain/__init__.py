"""Real terrain: DEM rasters, release areas and their coordinate reference systems.

This package sits below :mod:`fem_runout.config`: the case loader and schema call into it
(lazily), it never imports the config back at run time (``Case`` is an annotation only here),
and the data folder ``${FEM_RUNOUT_DATA}`` lives in :mod:`fem_runout.terrain.paths`.
"""

from fem_runout.terrain.dem import Raster, read_raster, sample_grid, sample_raster
from fem_runout.terrain.nodes import elevation_at, initial_depth_at

__all__ = [
    "Raster",
    "elevation_at",
    "initial_depth_at",
    "read_raster",
    "sample_grid",
    "sample_raster",
]
