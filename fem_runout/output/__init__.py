"""Outputs of a run: fields, time series, peak envelopes, pictures, hazard maps (GeoTIFF).

Every output is a :class:`fem_runout.callbacks.Callback`; nodal data is gathered to rank 0
in one rank-count independent order by :func:`gather_nodal`.
"""

from fem_runout.output.diagnostics import (
    SERIES_COLUMNS,
    PeakTracker,
    SeriesRecorder,
    compute_diagnostics,
    nodal_speed,
)
from fem_runout.output.fields import FIELD_NAMES, FieldWriter, read_vtx_bp4
from fem_runout.output.gather import (
    gather_nodal,
    global_max,
    global_min,
    global_sum,
    sorted_node_order,
)
from fem_runout.output.hazard import MAP_NAMES, HazardMaps
from fem_runout.output.pictures import Pictures, grid_shape, plot_series, render_depth

__all__ = [
    "FIELD_NAMES",
    "SERIES_COLUMNS",
    "FieldWriter",
    "HazardMaps",
    "MAP_NAMES",
    "PeakTracker",
    "Pictures",
    "SeriesRecorder",
    "compute_diagnostics",
    "gather_nodal",
    "global_max",
    "global_min",
    "global_sum",
    "grid_shape",
    "nodal_speed",
    "plot_series",
    "read_vtx_bp4",
    "render_depth",
    "sorted_node_order",
]
