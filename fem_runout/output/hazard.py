"""Hazard maps of a run: peak depth, speed and pressure, deposit and arrival time as rasters.

A callback on the Q1 fields ``h, hu, hv`` (every method has them). At finish the nodal maps
are gathered to rank 0 and written as GeoTIFF (and ESRI ASCII with ``output.ascii``). With
``terrain.dem`` they lie on the DEM grid (same shape, transform and CRS; cells outside the
domain are nodata); nodes on DEM cell centres give their values unchanged, other cells are
interpolated bilinearly (the arrival time over the nodes reached, :func:`arrival_over_reached`).
Without a DEM the rasters are the node
grid itself (one pixel per node, no CRS).

The summary's affected and deposit areas are counted on the DEM rasters' pixels when the case
has a DEM (:func:`raster_areas`: one measure for every mesh and cell size), else on the nodes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.output.envelopes import fold_envelopes
from fem_runout.output.gather import exact_global_sum, gather_nodal
from fem_runout.output.sampling import bed_cosine_nodes, ghosted, sample_q1
from fem_runout.terrain.dem import sample_grid

if TYPE_CHECKING:
    from fem_runout.callbacks import StepInfo
    from fem_runout.config import Case
    from fem_runout.solver_api import Solver

__all__ = ["MAP_NAMES", "NODATA", "GridTarget", "HazardMaps", "arrival_over_reached",
           "map_summary", "raster_areas",
           "write_rasters"]

NODATA = -9999.0
MAP_NAMES = ("peak_depth", "peak_depth_normal", "peak_speed", "peak_pressure", "deposit_depth",
             "arrival_time")
#: What each map holds (the GeoTIFF band description): GIS users compare depth maps of
#: models that report vertical depths with those of slope-normal thicknesses.
MAP_DESCRIPTIONS = {
    "peak_depth": "peak flow depth, vertical [m]",
    "peak_depth_normal": "peak flow thickness normal to the bed, vertical depth x cos(slope) [m]",
    "peak_speed": "peak speed, horizontal velocity [m/s]",
    "peak_pressure": "peak pressure rho v^2 [Pa]",
    "deposit_depth": "final depth, vertical [m]",
    "arrival_time": "first time the depth exceeds output.front_threshold [s]",
}


@dataclass(frozen=True)
class GridTarget:
    """Where rasters go: shape, transform and CRS, and the map coordinates of the pixels."""

    shape: tuple[int, int]
    transform: Any
    crs: Any

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-centre x (per column) and y (per row)."""
        t = self.transform
        rows, cols = self.shape
        return t.c + t.a * (np.arange(cols) + 0.5), t.f + t.e * (np.arange(rows) + 0.5)


def target_for(case: Case) -> GridTarget:
    """Return the DEM grid of the case, else the node grid (one pixel centred on each node)."""
    from rasterio.transform import from_origin

    if case.terrain.dem is not None:
        from fem_runout.terrain.dem import read_raster

        t = case.terrain
        dem = read_raster(case.resolve_input(t.dem), "terrain.dem", t.fill_nodata)
        return GridTarget(dem.shape, dem.transform, t.crs or dem.crs)
    xmin, xmax, ymin, ymax = case.domain.extent or (0.0, 1.0, 0.0, 1.0)
    nx, ny = case.domain.resolved_cells
    dx, dy = (xmax - xmin) / nx, (ymax - ymin) / ny
    return GridTarget((ny + 1, nx + 1), from_origin(xmin - dx / 2, ymax + dy / 2, dx, dy), None)


def mesh_target(case: Case, disc) -> GridTarget:
    """Return the DEM's grid, or (no DEM) one over the mesh's box at its finest cell size."""
    if case.terrain.dem is not None:
        return target_for(case)
    from rasterio.transform import from_origin

    xmin, xmax, ymin, ymax = disc.extent
    size = float(disc.min_cell_size)
    cols = max(1, int(np.ceil((xmax - xmin) / size)))
    rows = max(1, int(np.ceil((ymax - ymin) / size)))
    return GridTarget((rows, cols), from_origin(xmin, ymin + rows * size, size, size), None)


def to_target(grid: np.ndarray, extent: tuple[float, float, float, float],
              target: GridTarget, method: str = "bilinear") -> np.ndarray:
    """Resample a node grid (rows of increasing y) to the target pixels (NODATA outside)."""
    xmin, xmax, ymin, ymax = extent
    ny, nx = grid.shape[0] - 1, grid.shape[1] - 1
    dx, dy = (xmax - xmin) / nx, (ymax - ymin) / ny
    xc, yc = target.centres()
    tol = 1e-6 * max(dx, dy)
    cols = np.flatnonzero((xc >= xmin - tol) & (xc <= xmax + tol))
    rows = np.flatnonzero((yc >= ymin - tol) & (yc <= ymax + tol))
    out = np.full(target.shape, NODATA)
    X, Y = np.meshgrid(xc[cols], yc[rows])
    values = sample_grid(grid, xmin, dx, ymin, dy, X, Y, method)
    out[np.ix_(rows, cols)] = np.where(np.isfinite(values), values, NODATA)
    return out


def write_rasters(maps: dict[str, np.ndarray], target: GridTarget, out_dir: Path,
                  ascii_grids: bool = False) -> list[Path]:
    """Write each map as ``<name>.tif`` (and ``<name>.asc``) with the target's georeference."""
    import rasterio

    written = []
    profile = {"count": 1, "dtype": "float64", "height": target.shape[0],
               "width": target.shape[1], "transform": target.transform, "crs": target.crs,
               "nodata": NODATA}
    for name, values in maps.items():
        for suffix, driver in ((".tif", "GTiff"), (".asc", "AAIGrid")):
            if suffix == ".asc" and not ascii_grids:
                continue
            path = out_dir / f"{name}{suffix}"
            extra = {"compress": "deflate"} if driver == "GTiff" else {}
            with rasterio.open(path, "w", driver=driver, **profile, **extra) as dst:
                dst.write(values.astype(np.float64), 1)
                if driver == "GTiff" and name in MAP_DESCRIPTIONS:
                    dst.set_band_description(1, MAP_DESCRIPTIONS[name])
            written.append(path)
    return written


def _node_areas(shape: tuple[int, int], extent: tuple[float, float, float, float]) -> np.ndarray:
    """Dual-cell area of every node of a grid (halved on edges)."""
    ny, nx = shape[0] - 1, shape[1] - 1
    xmin, xmax, ymin, ymax = extent
    wx = np.full(nx + 1, (xmax - xmin) / nx)
    wy = np.full(ny + 1, (ymax - ymin) / ny)
    wx[[0, -1]] *= 0.5
    wy[[0, -1]] *= 0.5
    return np.outer(wy, wx)


def raster_areas(peak: np.ndarray, deposit: np.ndarray, target: GridTarget,
                 threshold: float) -> dict[str, float]:
    """Affected and deposit areas counted on the hazard rasters (pixels above ``threshold``).

    With a DEM the rasters are the DEM's own grid whatever the mesh, so these areas measure
    every run with the same pixels, the ones the GeoTIFFs show in a GIS. Counting the mesh's
    nodes instead weights each by its dual cell: at a flow's margin a 10 m node adds 100 m²
    where 5 m pixels add what the interpolated map covers (avaKot's corridor mesh: -4.7 %
    against the 5 m grid by nodes, -0.9 % by pixels; docs/meshes.md). NODATA pixels count
    as dry.
    """
    t = target.transform
    pixel = abs(t.a * t.e)
    return {"affected_area": float(np.count_nonzero(peak > threshold)) * pixel,
            "deposit_area": float(np.count_nonzero(deposit > threshold)) * pixel}


def arrival_over_reached(weighted: np.ndarray, reached: np.ndarray) -> np.ndarray:
    """Arrival time at sample points from the Q1 samples of ``t_i 1_i`` and ``1_i``.

    ``1_i`` marks the nodes the flow reached (``t_i`` finite). The ratio is the Q1 mean of
    the reached nodes' times with the weights renormalised over them: defined wherever a
    node of the cell was reached, so wherever the sampled peak depth exceeds the threshold
    (a plain Q1 sample of ``t_i`` is NaN as soon as one of the cell's nodes stayed dry, which
    left 1 076 of 11 509 wet pixels of DAMPM's avaKot corridor run without an arrival time).
    NaN where no node was reached.
    """
    ok = reached > 0.0
    return np.where(ok, weighted / np.where(ok, reached, 1.0), np.nan)


def bed_cosine(z: np.ndarray, extent: tuple[float, float, float, float]) -> np.ndarray:
    """``cosθ = 1/sqrt(1 + |∇Z|²)`` on a node grid (central differences, one-sided on edges)."""
    ny, nx = z.shape[0] - 1, z.shape[1] - 1
    dx, dy = (extent[1] - extent[0]) / nx, (extent[3] - extent[2]) / ny
    gy, gx = np.gradient(z, dy, dx)
    return 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)


def map_summary(g: dict[str, np.ndarray], extent: tuple[float, float, float, float],
                threshold: float) -> dict[str, float]:
    """Run-out length, travel angle, affected area and peaks from node grids.

    The run-out length is the largest horizontal distance from the highest released node to a
    node whose peak depth exceeded ``threshold``; the travel angle is ``atan(H / L)`` with
    ``H`` the drop between those two nodes.
    """
    area = g["area"] if "area" in g else _node_areas(g["z"].shape, extent)
    hit = g["peak_depth"] > threshold
    src = g["h0"] > threshold
    out = {"affected_area": float(area[hit].sum()), "peak_depth_max": float(g["peak_depth"].max()),
           "peak_speed_max": float(g["peak_speed"].max()),
           "peak_pressure_max": float(g["peak_pressure"].max()),
           "deposit_area": float(area[g["h"] > threshold].sum()),
           "runout_length": 0.0, "travel_angle_deg": float("nan")}
    if src.any() and hit.any():
        z = np.where(src, g["z"], -np.inf)
        top = np.unravel_index(int(np.argmax(z)), z.shape)
        dist = np.hypot(g["x"] - g["x"][top], g["y"] - g["y"][top])
        far = np.unravel_index(int(np.argmax(np.where(hit, dist, -1.0))), dist.shape)
        out["runout_length"] = float(dist[far])
        drop = float(g["z"][top] - g["z"][far])
        out["travel_angle_deg"] = float(np.degrees(np.arctan2(drop, dist[far])))
    return out


class HazardMaps:
    """Callback tracking per-node hazard quantities; writes rasters, maps and a summary.

    Tracked on the owned nodes after every step (no communication): peak depth, peak speed
    (nodes deeper than ``threshold``), peak pressure ``ρ v²``, first arrival time (depth above
    ``threshold``; 0 in the release) and the final depth (the deposit).

    Attributes:
        summary: After finish (every rank): volumes, peaks, affected area, run-out length.
        written: Files written (rank 0).
    """

    def __init__(self, case: Case, out_dir: str | Path | None, pictures: bool = True) -> None:
        """Configure the maps from the case (threshold, density, DEM grid, ``output.ascii``)."""
        self.case = case
        self.out_dir = None if out_dir is None else Path(out_dir)
        self.pictures = pictures
        self.threshold = float(case.output.front_threshold)
        self.density = float(case.material.density)
        self.summary: dict[str, Any] = {}
        self.written: list[Path] = []
        self._track: dict[str, np.ndarray] = {}
        self._resume: dict | None = None

    def _owned(self, solver: Solver) -> tuple[np.ndarray, ...]:
        n = solver.V.dofmap.index_map.size_local
        return tuple(solver.fields[k].x.array[:n].real.copy() for k in ("h", "hu", "hv", "z"))

    def save_state(self) -> dict:
        """Return the tracked maps in the global node order and the released volume."""
        return {"nodes": gather_nodal(self._V, self._track),
                "released_volume": self.summary["released_volume"]}

    def resume(self, state: dict) -> None:
        """Continue a checkpoint's maps (restored at :meth:`start`)."""
        self._resume = state

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Store the released state; print nothing (the API prints the released volume)."""
        self._V = solver.V
        h, _, _, z = self._owned(solver)
        n = h.size
        if self._resume is not None:
            from fem_runout.checkpoint import scatter_nodal

            local = scatter_nodal(solver.V, self._resume["nodes"])
            self._track = {k: np.ascontiguousarray(v[:n]) for k, v in local.items()}
            self.summary["released_volume"] = float(self._resume["released_volume"])
            self._resume = None
            return
        self._track = {"h0": h, "z": z, "peak_depth": h.copy(), "peak_speed": np.zeros(n),
                       "peak_pressure": np.zeros(n),
                       "arrival_time": np.where(h > self.threshold, info.t, np.nan)}
        self.summary["released_volume"] = exact_global_sum(solver.comm, solver.lumped_mass[:n] * h)
        self.step(solver, info)

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Fold the current state into the envelopes (on the flow's dofs: zero elsewhere)."""
        tr = self._track
        h, hu, hv = (solver.fields[k].x.array.real for k in ("h", "hu", "hv"))
        fold_envelopes(solver.flow_dofs(), h, hu, hv, self.threshold, tr["peak_depth"],
                       tr["peak_speed"], tr["peak_pressure"], tr["arrival_time"], info.t,
                       self.density)

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do at output times."""

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Gather (collective), then write the rasters, pictures and summary on rank 0."""
        h = self._owned(solver)[0]
        n = h.size
        deposit = exact_global_sum(solver.comm, solver.lumped_mass[:n] * h)
        outflow, dried = float(solver.outflow_volume), float(solver.dried_volume)
        released = self.summary["released_volume"]
        left = deposit + outflow + dried
        self.summary.update(deposit_volume=deposit, outflow_volume=outflow, dried_volume=dried,
                            mass_balance_error=(left - released) / released
                            if released else left)
        disc = getattr(solver, "disc", None)
        if disc is not None and not disc.structured:
            extra = self._finish_on_mesh(solver, disc, h, info.t)
        else:
            nodes = gather_nodal(solver.V, {**self._track, "h": h})
            extra = None
            if nodes is not None:
                extra = self._write(nodes, info)
        self.summary.update(solver.comm.bcast(extra, root=0))

    def _finish_on_mesh(self, solver: Solver, disc, h: np.ndarray,
                        info_t: float) -> dict[str, Any] | None:
        """Summary and rasters on an unstructured mesh (collective; the summary on rank 0).

        The summary uses the nodes with their lumped areas; the rasters are the Q1 fields
        sampled at the target's pixel centres (:mod:`.sampling`), nodata outside the mesh.
        """
        n = h.size
        cos = bed_cosine_nodes(disc, solver.fields["z"].x.array)
        track = {**self._track, "h": h, "area": disc.lumped_mass[:n], "cos": cos[:n]}
        nodes = gather_nodal(solver.V, track)
        summary = None
        if nodes is not None:
            summary = map_summary(nodes, disc.extent, self.threshold)
            summary["peak_depth_normal_max"] = float(np.max(nodes["peak_depth"] * nodes["cos"]))
        with_dem = self.case.terrain.dem is not None
        if self.out_dir is None and not with_dem:
            return summary
        target = mesh_target(self.case, disc)
        xs, ys = target.centres()
        names = ("peak_depth", "peak_speed", "peak_pressure", "h", "h0", "z")
        arrival = track["arrival_time"]
        reached = np.isfinite(arrival)
        local = {"cos": cos, **ghosted(disc, {**{k: track[k] for k in names},
                                              "arrival_time": np.where(reached, arrival, 0.0),
                                              "reached": reached.astype(float)})}
        grids = sample_q1(disc, local, xs, ys[::-1])
        if grids is not None:
            grids["arrival_time"] = arrival_over_reached(grids.pop("arrival_time"),
                                                         grids.pop("reached"))
            g = {k: v[::-1] for k, v in grids.items()}  # rows from the top, as the raster
            g["peak_depth_normal"] = g["peak_depth"] * g["cos"]
            g["deposit_depth"] = g["h"]
            rasters = {k: np.where(np.isfinite(g[k]), g[k], NODATA) for k in MAP_NAMES}
            if with_dem:
                summary.update(raster_areas(rasters["peak_depth"], rasters["deposit_depth"],
                                            target, self.threshold))
            if self.out_dir is None:
                return summary
            self.written += write_rasters(rasters, target, self.out_dir, self.case.output.ascii)
            if self.pictures:
                self._pictures_on_mesh(grids, xs, ys[::-1], info_t)
        return summary

    def _pictures_on_mesh(self, grids: dict[str, np.ndarray], xs: np.ndarray, ys: np.ndarray,
                          t: float) -> None:
        """Rank 0: the hazard map and deposit pictures from the sampled grids (rows up)."""
        from fem_runout.output.maps import draw_maps

        g = {k: np.nan_to_num(v) if k != "z" else v for k, v in grids.items()}
        g["x"], g["y"] = np.meshgrid(xs, ys)
        extent = (float(xs[0]), float(xs[-1]), float(ys[0]), float(ys[-1]))
        self.written += draw_maps(g, extent, self.out_dir, self.case.name, self.threshold, t)

    def _write(self, nodes: dict[str, np.ndarray], info: StepInfo) -> dict[str, float]:
        """Rank 0: grids, summary, rasters and pictures."""
        nx, ny = self.case.domain.resolved_cells
        extent = self.case.domain.extent or (0.0, 1.0, 0.0, 1.0)
        g = {k: np.reshape(v, (ny + 1, nx + 1)) for k, v in nodes.items()}
        summary = map_summary(g, extent, self.threshold)
        g["peak_depth_normal"] = g["peak_depth"] * bed_cosine(g["z"], extent)
        summary["peak_depth_normal_max"] = float(g["peak_depth_normal"].max())
        with_dem = self.case.terrain.dem is not None
        if self.out_dir is None and not with_dem:
            return summary
        target = target_for(self.case)
        g["deposit_depth"] = g["h"]
        names = MAP_NAMES if self.out_dir is not None else ("peak_depth", "deposit_depth")
        maps = {name: to_target(g[name], extent, target) for name in names
                if name != "arrival_time"}
        if "arrival_time" in names:
            reached = np.isfinite(g["arrival_time"])
            weighted = to_target(np.where(reached, g["arrival_time"], 0.0), extent, target)
            share = to_target(reached.astype(float), extent, target)  # NODATA outside: < 0
            arrival = arrival_over_reached(weighted, np.maximum(share, 0.0))
            maps["arrival_time"] = np.where(np.isfinite(arrival), arrival, NODATA)
        if with_dem:
            summary.update(raster_areas(maps["peak_depth"], maps["deposit_depth"], target,
                                        self.threshold))
        if self.out_dir is None:
            return summary
        self.written += write_rasters(maps, target, self.out_dir, self.case.output.ascii)
        if self.pictures:
            from fem_runout.output.maps import draw_maps

            t = self.case.terrain
            if t.dem is not None and t.fill_nodata:
                from fem_runout.terrain.dem import read_raster, sample_raster

                raw = read_raster(self.case.resolve_input(t.dem), "terrain.dem")
                g["filled"] = np.isnan(sample_raster(raw, g["x"], g["y"]))

            self.written += draw_maps(g, extent, self.out_dir, self.case.name, self.threshold,
                                      info.t)
        return summary
