"""Map pictures of a run: a hillshade map (matplotlib) and a 3D view of the deposit (pyvista)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

__all__ = ["draw_maps", "hillshade", "plot_hazard_map", "render_deposit_3d"]


def hillshade(z: np.ndarray, dx: float, dy: float, azimuth: float = 315.0,
              altitude: float = 45.0) -> np.ndarray:
    """Hillshade in [0, 1] of a grid with rows of increasing y (sun from the north-west)."""
    gy, gx = np.gradient(z, dy, dx)
    slope = np.arctan(np.hypot(gx, gy))
    aspect = np.arctan2(-gx, gy)
    az, alt = np.radians(azimuth), np.radians(altitude)
    shade = np.sin(alt) * np.cos(slope) + np.cos(alt) * np.sin(slope) * np.cos(az - aspect)
    return np.clip(shade, 0.0, 1.0)


def plot_hazard_map(g: dict[str, np.ndarray], extent: tuple[float, float, float, float],
                    path: Path, title: str, threshold: float) -> Path:
    """Hillshade, peak flow depth, the release outline (red) and the deposit outline (black).

    Args:
        g: Node grids (rows of increasing y): ``x, y, z, h0, peak_depth, h`` and optionally
            ``filled`` (True where the DEM had nodata that was filled), drawn veiled.
        extent: ``(xmin, xmax, ymin, ymax)``.
        path: PNG to write.
        title: Figure title.
        threshold: Depth [m] above which a node counts as reached / released / deposited.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    ny, nx = g["z"].shape[0] - 1, g["z"].shape[1] - 1
    dx, dy = (extent[1] - extent[0]) / nx, (extent[3] - extent[2]) / ny
    ratio = (extent[3] - extent[2]) / (extent[1] - extent[0])
    fig = Figure(figsize=(7.5, max(4.0, min(12.0, 6.5 * ratio + 1.0))), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    kw = {"origin": "lower", "extent": extent}
    ax.imshow(hillshade(g["z"], dx, dy), cmap="gray", vmin=0, vmax=1, **kw)
    peak = np.ma.masked_less_equal(g["peak_depth"], threshold)
    im = ax.imshow(peak, cmap="viridis", alpha=0.85, **kw)
    fig.colorbar(im, ax=ax, label="peak flow depth [m]", shrink=0.8)
    handles = []
    if "filled" in g and g["filled"].any():
        veil = np.ma.masked_where(~g["filled"], np.ones(g["filled"].shape))
        ax.imshow(veil, cmap="gray", vmin=0, vmax=1, alpha=0.55, **kw)
        handles.append(Patch(facecolor="white", edgecolor="grey", label="DEM nodata (filled)"))
    for key, colour, label in (("h0", "red", "release"), ("h", "black", "deposit")):
        if (g[key] > threshold).any():
            ax.contour(g["x"], g["y"], (g[key] > threshold).astype(float), levels=[0.5],
                       colors=colour, linewidths=1.2)
            handles.append(Line2D([], [], color=colour, label=label))
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize=8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.tick_params(labelsize=7)
    ax.set_title(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def _crop(g: dict[str, np.ndarray], threshold: float, margin: int = 10) -> dict[str, np.ndarray]:
    """Return the grids around the nodes ever reached (plus ``margin`` nodes)."""
    hit = (g["peak_depth"] > threshold) | (g["h0"] > threshold)
    if not hit.any():
        return g
    rows, cols = np.flatnonzero(hit.any(axis=1)), np.flatnonzero(hit.any(axis=0))
    r0, r1 = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, hit.shape[0])
    c0, c1 = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, hit.shape[1])
    return {k: v[r0:r1, c0:c1] for k, v in g.items() if v.shape == hit.shape}


def render_deposit_3d(g: dict[str, np.ndarray], path: Path, threshold: float,
                      title: str) -> Path | None:
    """3-D view of the deposit on the terrain around the path, seen from beyond the deposit.

    The camera looks back up the path: it stands on the side of the deposit opposite to the
    release, 40° above the horizon.
    """
    import pyvista

    from fem_runout.output.pictures import use_headless_vtk

    c = _crop(g, threshold)
    if min(c["z"].shape) < 2:
        return None
    grid = pyvista.StructuredGrid(c["x"].T, c["y"].T, c["z"].T)
    depth = np.where(c["h"] > threshold, c["h"], np.nan)
    grid.point_data["deposit depth [m]"] = depth.ravel()
    wet = np.isfinite(depth)
    src, dep = c["h0"] > threshold, wet if wet.any() else c["peak_depth"] > threshold
    look = np.zeros(2)
    if src.any() and dep.any():
        look = np.array([c["x"][dep].mean() - c["x"][src].mean(),
                         c["y"][dep].mean() - c["y"][src].mean()])
    look = look / np.hypot(*look) if np.hypot(*look) > 0 else np.array([0.0, -1.0])
    centre = np.array([c["x"].mean(), c["y"].mean(), float(np.nanmean(c["z"]))])
    size = float(np.hypot(np.ptp(c["x"]), np.ptp(c["y"])))
    elev = np.radians(40.0)
    eye = centre + 1.3 * size * np.array([look[0] * np.cos(elev), look[1] * np.cos(elev),
                                           np.sin(elev)])
    use_headless_vtk()
    plotter = pyvista.Plotter(off_screen=True, window_size=(1200, 800))
    try:
        plotter.set_background("white")
        clim = (threshold, float(np.nanmax(depth)) if wet.any() else 1.0)
        plotter.add_mesh(grid, scalars="deposit depth [m]", cmap="viridis", clim=clim,
                         nan_color="lightgrey", scalar_bar_args={
                             "color": "black", "vertical": True, "position_x": 0.86,
                             "position_y": 0.15})
        plotter.add_title(title, font_size=12, color="black")
        plotter.camera_position = [tuple(eye), tuple(centre), (0.0, 0.0, 1.0)]
        plotter.reset_camera()  # keep the direction, fit the crop in the view
        plotter.camera.zoom(1.05)
        path.parent.mkdir(parents=True, exist_ok=True)
        plotter.screenshot(str(path))
    finally:
        plotter.close()
    return path


def draw_maps(g: dict[str, np.ndarray], extent: tuple[float, float, float, float],
              out_dir: Path, name: str, threshold: float, t: float) -> list[Path]:
    """Draw ``hazard_map.png`` and ``deposit_3d.png`` (a failure is a warning, not an error)."""
    jobs = [
        ("hazard_map.png", lambda p: plot_hazard_map(
            g, extent, p, f"{name}: peak flow depth, release and deposit", threshold)),
        ("deposit_3d.png", lambda p: render_deposit_3d(
            g, p, threshold, f"{name}: deposit at t = {t:.4g} s")),
    ]
    written = []
    for file, job in jobs:
        try:
            path = job(out_dir / file)
        except (ImportError, RuntimeError, OSError, ValueError) as err:
            warnings.warn(f"could not draw {file}: {err}", stacklevel=2)
            continue
        if path is not None:
            written.append(Path(path))
    return written
