"""Real terrain: DEM rasters, release areas and their coordinate reference systems."""

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
