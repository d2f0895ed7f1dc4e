"""gmsh size fields of an outline mesh (``domain.refine``), combined with Min.

- ``line``: gmsh Distance field of helper curves along the line (not part of the domain's
  surface), then a Threshold field: ``size`` at the line, linear to ``cell_size`` at
  ``distance``;
- ``release``: the same law of the distance to the release polygons (0 inside them),
  computed with shapely on a grid of spacing ``size / 2`` and handed to gmsh as a PostView
  field (bilinear between grid points, outside the grid the field does not refine);
- ``terrain``: ``h = sqrt(8 tolerance / λ)`` clamped to ``[size, cell_size]``, λ the largest
  absolute eigenvalue of the DEM's Hessian after Gaussian smoothing over ``size`` (the
  bilinear bed of a cell of size ``h`` then deviates from the DEM by at most about
  ``tolerance``), on the DEM cell centres, as a PostView field.

The background field is ``Min(cell_size, fields...)``; gmsh bounds it by ``min_size`` and
``cell_size`` (``Mesh.MeshSizeMin``/``Max``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.meshing.shapes import release_union

if TYPE_CHECKING:
    from fem_runout.config import Case
    from fem_runout.config.domain import RefineSpec

__all__ = ["add_size_fields", "grow", "terrain_size"]

_MAX_GRID = 2_000_000  # largest number of grid cells of a PostView field


def grow(d: np.ndarray, size: float, cell_size: float, distance: float) -> np.ndarray:
    """Size ``size`` at distance 0, linear to ``cell_size`` at ``distance``, then constant."""
    return size + (cell_size - size) * np.clip(d / distance, 0.0, 1.0)


def _field(kind: str, **numbers: float | list[int]) -> int:
    import gmsh

    tag = gmsh.model.mesh.field.add(kind)
    for name, value in numbers.items():
        if isinstance(value, list):
            gmsh.model.mesh.field.setNumbers(tag, name, value)
        else:
            gmsh.model.mesh.field.setNumber(tag, name, value)
    return tag


def _line_field(curves: list[int], longest: float, item: RefineSpec, cell_size: float) -> int:
    """Threshold(Distance(curves)): ``size`` at the line, ``cell_size`` at ``distance``.

    The Distance field samples each curve at ``Sampling`` points: a quarter of ``size`` apart
    on the longest one.
    """
    sampling = min(20_000, max(2, math.ceil(longest / (item.size / 4)) + 1))
    dist = _field("Distance", CurvesList=curves, Sampling=sampling)
    assert item.distance is not None
    return _field("Threshold", InField=dist, SizeMin=item.size, SizeMax=cell_size, DistMin=0.0,
                  DistMax=item.distance)


def _grid_view(x: np.ndarray, y: np.ndarray, values: np.ndarray, views: list[int]) -> int:
    """PostView field of ``values[j, i]`` at ``(x[i], y[j])`` (quadrilateral list view)."""
    import gmsh

    corners = [(slice(None, -1), slice(None, -1)), (slice(None, -1), slice(1, None)),
               (slice(1, None), slice(1, None)), (slice(1, None), slice(None, -1))]
    gx, gy = np.meshgrid(x, y)
    parts = [np.stack([a[c] for c in corners], axis=-1).reshape(-1, 4) for a in (gx, gy)]
    data = np.hstack([parts[0], parts[1], np.zeros_like(parts[0]),
                      np.stack([values[c] for c in corners], axis=-1).reshape(-1, 4)])
    view = gmsh.view.add("fem_runout size field")
    views.append(view)
    gmsh.view.addListData(view, "SQ", len(data), data.ravel())
    return _field("PostView", ViewTag=view)


def _axis(lo: float, hi: float, step: float) -> np.ndarray:
    n = max(1, math.ceil((hi - lo) / step))
    return lo + (hi - lo) * np.arange(n + 1) / n


def _release_field(case: Case, poly: Any, item: RefineSpec, views: list[int]) -> int:
    """Grid field of the distance to the release polygons."""
    import shapely

    release, d = release_union(case), case.domain
    assert release is not None and item.distance is not None and d.cell_size is not None
    bx0, by0, bx1, by1 = shapely.intersection(release.buffer(item.distance), poly.envelope).bounds
    step = max(item.size / 2, math.sqrt((bx1 - bx0) * (by1 - by0) / _MAX_GRID))
    x, y = _axis(bx0, bx1, step), _axis(by0, by1, step)
    gx, gy = np.meshgrid(x, y)
    dist = shapely.distance(release, shapely.points(gx, gy))
    return _grid_view(x, y, grow(dist, item.size, d.cell_size, item.distance), views)


def terrain_size(z: np.ndarray, res: float, item: RefineSpec, cell_size: float) -> np.ndarray:
    """Cell size from the bed's curvature: ``sqrt(8 tolerance / λ)`` in ``[size, cell_size]``.

    Args:
        z: Elevations on a grid of spacing ``res`` (NaN: filled from the nearest value).
        res: Grid spacing [m].
        item: The ``terrain`` refine field (``size``, ``tolerance``).
        cell_size: The largest cell size [m].

    Returns:
        The cell size [m] at every grid point.
    """
    from scipy import ndimage

    z = np.asarray(z, dtype=np.float64)
    bad = ~np.isfinite(z)
    if bad.all():
        return np.full(z.shape, cell_size)
    if bad.any():
        z = z[tuple(ndimage.distance_transform_edt(bad, return_distances=False,
                                                   return_indices=True))]
    sigma = item.size / res
    pad = math.ceil(4 * sigma) + 1  # odd reflection continues a plane as a plane at the edges
    z = ndimage.gaussian_filter(np.pad(z, pad, mode="reflect", reflect_type="odd"), sigma)
    zx, zy = np.gradient(z, res, axis=1), np.gradient(z, res, axis=0)  # exact on quadratics
    zxx, zyy, zxy = (a[pad:-pad, pad:-pad] for a in (np.gradient(zx, res, axis=1),
                                                      np.gradient(zy, res, axis=0),
                                                      np.gradient(zx, res, axis=0)))
    lam = np.abs(0.5 * (zxx + zyy)) + np.sqrt(0.25 * (zxx - zyy) ** 2 + zxy**2)
    assert item.tolerance is not None
    return np.clip(np.sqrt(8.0 * item.tolerance / np.maximum(lam, 1e-30)), item.size, cell_size)


def _terrain_field(case: Case, poly: Any, item: RefineSpec, views: list[int]) -> int:
    """Grid field of the curvature size on the DEM cell centres around the outline."""
    from fem_runout.terrain.dem import read_raster

    t, d = case.terrain, case.domain
    assert t.dem is not None and d.cell_size is not None
    raster = read_raster(case.resolve_input(t.dem), "terrain.dem", t.fill_nodata)
    xc, yc = raster.centres()
    res = raster.res[0]
    margin = 4 * item.size + 2 * res
    x0, y0, x1, y1 = poly.bounds
    cols = np.flatnonzero((xc >= x0 - margin) & (xc <= x1 + margin))
    rows = np.flatnonzero((yc >= y0 - margin) & (yc <= y1 + margin))
    if len(cols) < 2 or len(rows) < 2:
        raise CaseError("domain.outline: lies outside the DEM (terrain.dem)")
    z = raster.values[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1][::-1]  # rows south first
    size = terrain_size(z, res, item, d.cell_size)
    stride = max(1, math.ceil(math.sqrt(size.size / _MAX_GRID)))
    y = yc[rows][::-1]
    return _grid_view(xc[cols][::stride], y[::stride], size[::stride, ::stride], views)


def add_size_fields(case: Case, poly: Any, curves: dict[int, tuple[list[int], float]],
                    views: list[int]) -> None:
    """Set the background size field ``Min(cell_size, refine fields)`` of the current model.

    Args:
        case: The resolved case (``domain.refine``, ``cell_size``).
        poly: The outline polygon (shapely).
        curves: For each ``line`` refine field (by index): its helper curves and the length
            of the longest.
        views: Receives the tags of the gmsh views made (to be removed after meshing).
    """
    import gmsh

    d = case.domain
    assert d.cell_size is not None
    fields = [_field("MathEval")]
    gmsh.model.mesh.field.setString(fields[0], "F", repr(float(d.cell_size)))
    for i, item in enumerate(d.refine or ()):
        if item.kind == "line":
            fields.append(_line_field(*curves[i], item, d.cell_size))
        elif item.kind == "release":
            fields.append(_release_field(case, poly, item, views))
        else:
            fields.append(_terrain_field(case, poly, item, views))
    gmsh.model.mesh.field.setAsBackgroundMesh(_field("Min", FieldsList=fields))
