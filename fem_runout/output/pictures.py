"""Pictures of a run: time-series panels (matplotlib) and depth maps on the terrain (pyvista)."""

from __future__ import annotations

import ctypes.util
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from mpi4py import MPI  # noqa: F401 - before dolfinx

# isort: split

import numpy as np

from fem_runout.output.gather import gather_nodal

if TYPE_CHECKING:
    from fem_runout.callbacks import StepInfo
    from fem_runout.output.diagnostics import PeakTracker, SeriesRecorder
    from fem_runout.solver_api import Solver

__all__ = ["Pictures", "grid_shape", "plot_series", "render_depth", "use_headless_vtk"]

#: Largest raster on which an unstructured mesh's depth pictures are drawn.
MAX_PIXELS = 1_000_000

#: VTK's variable naming the OpenGL render window class to create (VTK >= 9.4).
VTK_WINDOW_ENV = "VTK_DEFAULT_OPENGL_WINDOW"


def use_headless_vtk() -> str | None:
    """Make VTK render off-screen with EGL when there is no display; call before a render window.

    VTK (>= 9.4) picks its OpenGL window at run time, trying X first: without a display it
    logs ``bad X server connection. DISPLAY=`` and then falls back to EGL. Naming EGL in
    ``VTK_DEFAULT_OPENGL_WINDOW`` skips the X attempt and its message; the pictures are the
    same. Nothing changes when a display is set (X or Wayland), when the variable is already
    set (the user's choice wins), or when no EGL library is installed (VTK's own fallbacks
    then apply: a forced window class that fails cannot be recovered from).

    Returns:
        The render window class in the environment, or None (VTK detects it).
    """
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return os.environ.get(VTK_WINDOW_ENV)
    if VTK_WINDOW_ENV not in os.environ and ctypes.util.find_library("EGL") is not None:
        os.environ[VTK_WINDOW_ENV] = "vtkEGLRenderWindow"
    return os.environ.get(VTK_WINDOW_ENV)


def plot_series(series: dict[str, np.ndarray], path: str | Path, title: str = "") -> Path:
    """Plot the diagnostics time series (see :class:`SeriesRecorder`) to a PNG.

    Panels: volume and mass error, kinetic energy, max depth and max speed, front x.

    Args:
        series: Columns ``t, volume, mass_error, kinetic_energy, max_depth, max_speed,
            front_x``.
        path: PNG file to write.
        title: Figure title.

    Returns:
        The path written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = np.asarray(series["t"])
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharex=True)
    panels = [
        (axes[0, 0], "volume", "volume [m³]", "mass_error", "mass error [-]"),
        (axes[0, 1], "kinetic_energy", "kinetic energy [J]", None, None),
        (axes[1, 0], "max_depth", "max depth [m]", "max_speed", "max speed [m/s]"),
        (axes[1, 1], "front_x", "front x [m]", None, None),
    ]
    for ax, left, left_label, right, right_label in panels:
        ax.plot(t, series[left], color="tab:blue", marker=".", ms=3)
        ax.set_ylabel(left_label, color="tab:blue")
        ax.grid(True, alpha=0.3)
        if right is not None:
            twin = ax.twinx()
            twin.plot(t, series[right], color="tab:red", marker=".", ms=3)
            twin.set_ylabel(right_label, color="tab:red")
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    if title:
        fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def grid_shape(x: np.ndarray, y: np.ndarray) -> tuple[int, int] | None:
    """Infer ``(nx, ny)`` cells of a structured grid from its node coordinates.

    Args:
        x: Node x coordinates.
        y: Node y coordinates.

    Returns:
        ``(nx, ny)`` if the nodes form a full ``(nx + 1) x (ny + 1)`` grid, else ``None``.
    """
    scale = max(float(np.ptp(x)), float(np.ptp(y)), 1.0) * 1e-9
    nxp = np.unique(np.round(x / scale)).size
    nyp = np.unique(np.round(y / scale)).size
    if nxp * nyp != x.size or nxp < 2 or nyp < 2:
        return None
    return nxp - 1, nyp - 1


def render_depth(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    h: np.ndarray,
    nx: int,
    ny: int,
    path: str | Path,
    threshold: float,
    title: str = "Flow depth",
    label: str = "depth [m]",
) -> Path | None:
    """Render the terrain surface coloured by depth (grey where dry) to a PNG, off-screen.

    Args:
        x: Node x coordinates sorted by ``(y, x)`` (as from :func:`gather_nodal`).
        y: Node y coordinates, same order.
        z: Terrain elevation, same order.
        h: Depth (or any nodal field to colour by), same order.
        nx: Number of cells in x.
        ny: Number of cells in y.
        path: PNG file to write.
        threshold: Nodes with ``h <= threshold`` are drawn as bare (grey) terrain.
        title: Picture title.
        label: Scalar bar title.

    Returns:
        The path written, or ``None`` (with a warning) if pyvista is not available.
    """
    try:
        import pyvista
    except ImportError as err:  # pragma: no cover - pyvista is a dependency
        warnings.warn(f"pyvista unavailable, no depth picture: {err}", stacklevel=2)
        return None
    pyvista.OFF_SCREEN = True
    use_headless_vtk()
    shape = (ny + 1, nx + 1)
    inside = np.isfinite(z)  # a mesh sampled on a raster: NaN outside its outline
    zf = np.where(inside, z, np.nanmin(z) if inside.any() else 0.0)
    grid = pyvista.StructuredGrid(*(np.reshape(a, shape).T for a in (x, y, zf)))
    depth = np.where(inside & (h > threshold), h, np.nan)
    grid.point_data[label] = depth  # StructuredGrid points run x fastest: the sorted order
    if not inside.all():
        grid = grid.extract_points(inside, adjacent_cells=False)
    wet = np.isfinite(depth)
    clim = (float(threshold), float(depth[wet].max()) if wet.any() else 1.0)
    plotter = pyvista.Plotter(off_screen=True, window_size=(1200, 800))
    try:
        plotter.set_background("white")
        plotter.add_mesh(
            grid,
            scalars=label,
            cmap="viridis",
            clim=clim,
            nan_color="lightgrey",
            show_edges=False,
            scalar_bar_args={"title": label, "color": "black", "vertical": True},
        )
        plotter.add_title(title, font_size=12, color="black")
        plotter.view_xy()
        plotter.camera.Elevation(-40.0)
        plotter.reset_camera()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        plotter.screenshot(str(path))
    finally:
        plotter.close()
    return path


class Pictures:
    """Callback drawing the pictures of a run at finish (gather collective, drawing on rank 0).

    Writes ``series.png`` (if a :class:`SeriesRecorder` is given), ``depth.png`` (final depth)
    and ``peak_depth.png`` (if a :class:`PeakTracker` is given) into ``out_dir``. A picture
    that cannot be drawn (no pyvista, no off-screen context) gives a warning, not an error. On
    an unstructured mesh the depth maps are drawn from the fields sampled on a raster.
    """

    def __init__(
        self,
        out_dir: str | Path,
        title: str,
        recorder: SeriesRecorder | None = None,
        peaks: PeakTracker | None = None,
        threshold: float = 1e-3,
    ) -> None:
        """Configure the pictures.

        Args:
            out_dir: Output folder.
            title: Title of the run, used in every picture.
            recorder: Source of the time series, if any.
            peaks: Source of the peak depth envelope, if any.
            threshold: Dry threshold [m] for the depth maps.
        """
        self.out_dir = Path(out_dir)
        self.title = title
        self.recorder = recorder
        self.peaks = peaks
        self.threshold = float(threshold)
        self.written: list[Path] = []

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do at start."""

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do after a step."""

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do at output times."""

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Gather the final state (collective) and draw the pictures on rank 0."""
        disc = getattr(solver, "disc", None)
        if disc is not None and not disc.structured:
            nodes = self._sampled(solver, disc)
            envelope = None if nodes is None else nodes.pop("envelope")
        else:
            fields = {k: solver.fields[k].x.array.real for k in ("h", "z")}
            nodes = gather_nodal(solver.V, fields)
            envelope = self.peaks.gathered() if self.peaks is not None else None
        if nodes is None:
            return
        jobs: list[tuple[str, Callable[[Path], Path | None]]] = []
        if self.recorder is not None:
            series = self.recorder.series
            jobs.append(("series.png", lambda p: plot_series(series, p, self.title)))
        shape = nodes.pop("shape", None) or grid_shape(nodes["x"], nodes["y"])
        if shape is None:
            warnings.warn("nodes are not a structured grid: no depth pictures", stacklevel=2)
        else:
            maps = [("depth.png", nodes["h"], f"{self.title}: depth at t = {info.t:.3g} s")]
            if envelope is not None:
                maps.append(("peak_depth.png", envelope["peak_depth"], f"{self.title}: peak depth"))
            for name, values, caption in maps:
                jobs.append((name, self._depth_job(nodes, values, shape, caption)))
        for name, job in jobs:
            try:
                written = job(self.out_dir / name)
            except (ImportError, RuntimeError, OSError, ValueError) as err:
                warnings.warn(f"could not draw {name}: {err}", stacklevel=2)
                continue
            if written is not None:
                self.written.append(Path(written))

    def _sampled(self, solver: Solver, disc) -> dict | None:
        """Return the final depth, bed and peak depth of a mesh on a raster (collective).

        Pixels of the shortest cell edge over the mesh's bounding box (at most
        :data:`MAX_PIXELS`), the Q1 fields sampled at their centres (:mod:`.sampling`), NaN
        outside the mesh: the pictures of an unstructured run look like a grid run's. None
        on ranks other than 0.
        """
        from fem_runout.output.sampling import ghosted, sample_q1

        arrays = {k: solver.fields[k].x.array.real for k in ("h", "z")}
        if self.peaks is not None:
            arrays["peak_depth"] = self.peaks.functions()[0].x.array.real
        local = ghosted(disc, arrays)
        xmin, xmax, ymin, ymax = disc.extent
        size = max(disc.min_cell_size, np.sqrt((xmax - xmin) * (ymax - ymin) / MAX_PIXELS))
        nx = max(2, int(np.ceil((xmax - xmin) / size)))
        ny = max(2, int(np.ceil((ymax - ymin) / size)))
        xs, ys = np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1)
        grids = sample_q1(disc, local, xs, ys)
        if grids is None:
            return None
        x, y = (a.ravel() for a in np.meshgrid(xs, ys))
        peak = grids.get("peak_depth")
        return {"x": x, "y": y, "z": grids["z"].ravel(), "h": grids["h"].ravel(),
                "shape": (nx, ny),
                "envelope": None if peak is None else {"peak_depth": peak.ravel()}}

    def _depth_job(
        self, nodes: dict[str, np.ndarray], values: np.ndarray, shape: tuple[int, int], title: str
    ) -> Callable[[Path], Path | None]:
        """Return a function of the PNG path that draws ``values`` over the terrain."""

        def job(path: Path) -> Path | None:
            x, y, z = nodes["x"], nodes["y"], nodes["z"]
            return render_depth(x, y, z, values, *shape, path, self.threshold, title)

        return job
