"""Check an outline or a mesh file when the case is loaded, and fill ``domain.extent``.

Called by :func:`fem_runout.terrain.resolve.resolve_terrain` (after the DEM's CRS is settled)
for ``domain.outline`` and ``domain.mesh``. It reads the files, checks the geometry against the
sizes, the DEM and the release, and returns the case with ``domain.extent`` = the bounding box
(and, for a mesh file, ``cell_size`` = its mean edge length). Relative input paths become
absolute so that ``case.resolved.yaml`` loads from anywhere. Every problem is a
:class:`~fem_runout.errors.CaseError` naming the key (exit code 2 on the command line).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.meshing.mshfile import read_msh
from fem_runout.meshing.quadmesh import mesh_quality
from fem_runout.meshing.shapes import case_line, case_outline, check_outline, release_union
from fem_runout.terrain.paths import DATA_ENV, DATA_PLACEHOLDER, data_folder

if TYPE_CHECKING:
    from fem_runout.config import Case
    from fem_runout.config.domain import RefineSpec

__all__ = ["resolve_domain"]


def _require_file(case: Case, key: str, value: Any) -> None:
    """Refuse a missing input file; for ``${FEM_RUNOUT_DATA}`` paths say where data come from."""
    if not isinstance(value, str) or case.resolve_input(value).is_file():
        return
    hint = ""
    if DATA_PLACEHOLDER in value:
        hint = f"; {DATA_ENV} names the data folder (now '{data_folder()}')"
    raise CaseError(f"{key}: file '{case.resolve_input(value)}' does not exist{hint}")


def _portable(case: Case, value: Any) -> Any:
    """Return an input path that resolves the same from anywhere (absolute or data folder)."""
    if not isinstance(value, str) or DATA_PLACEHOLDER in value:
        return value
    return str(case.resolve_input(value).resolve())


def _same_crs(a: str, b: str) -> bool:
    """Whether two CRS texts (EPSG code, WKT) are the same (an unreadable one: assume so)."""
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    try:
        ca, cb = CRS.from_user_input(a), CRS.from_user_input(b)
    except CRSError:
        return True
    return ca == cb or (ca.to_epsg() is not None and ca.to_epsg() == cb.to_epsg())


def _check_crs(case: Case, crs: str | None, key: str) -> None:
    run = case.terrain.crs
    if crs is not None and run is not None and not _same_crs(crs, run):
        raise CaseError(f"{key}: its CRS {crs} differs from the run's {run} (terrain.crs or the "
                        "DEM's); reproject it")


def _check_refine(case: Case, poly: Any, i: int, item: RefineSpec) -> RefineSpec:
    """Check one refine field against the case; return it with a portable line path."""
    key = f"domain.refine[{i}]"
    if item.kind == "terrain" and case.terrain.dem is None:
        raise CaseError(f"{key}: kind 'terrain' needs terrain.dem (the bed curvature comes "
                        "from the DEM)")
    if item.kind == "release" and release_union(case) is None:
        raise CaseError(f"{key}: kind 'release' needs release polygons "
                        "(initial.release[*].polygon)")
    if item.kind != "line":
        return item
    _require_file(case, f"{key}.line", item.line)
    shape = case_line(case, i)
    _check_crs(case, shape.crs, f"{key}.line")
    if not shape.geom.intersects(poly):
        raise CaseError(f"{key}.line: lies outside domain.outline; allowed: a line that runs "
                        "(at least partly) inside the outline")
    return item.model_copy(update={"line": _portable(case, item.line)})


def _check_release(case: Case, region: Any, key: str) -> None:
    release = release_union(case)
    if release is not None and not release.intersects(region):
        raise CaseError(f"initial.release: the release polygons lie outside {key}")


def _check_dem(case: Case, x: np.ndarray, y: np.ndarray, bounds: tuple[float, ...],
               key: str) -> None:
    """Refuse an area reaching outside the DEM's cell centres, or points on nodata."""
    from fem_runout.terrain.dem import read_raster, sample_raster

    t = case.terrain
    if t.dem is None:
        return
    raster = read_raster(case.resolve_input(t.dem), "terrain.dem", t.fill_nodata)
    xmin, xmax, ymin, ymax = raster.centre_extent()
    bx0, by0, bx1, by1 = bounds
    tol = 1e-9 * max(abs(xmax) + abs(ymax), 1.0)
    if bx0 < xmin - tol or bx1 > xmax + tol or by0 < ymin - tol or by1 > ymax + tol:
        raise CaseError(f"{key}: reaches outside the DEM '{raster.path.name}' (x {bx0:.6g} .. "
                        f"{bx1:.6g}, y {by0:.6g} .. {by1:.6g}; the DEM's cell centres span x "
                        f"{xmin:.6g} .. {xmax:.6g}, y {ymin:.6g} .. {ymax:.6g}); allowed: an "
                        "area inside the DEM")
    z = sample_raster(raster, x, y)
    bad = np.isnan(z)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CaseError(f"{key}: {int(bad.sum())} points of the area fall on nodata cells of "
                        f"'{raster.path.name}' (e.g. x={x[i]:.6g}, y={y[i]:.6g}); set "
                        "terrain.fill_nodata: true or keep the area inside the data")


def _dem_points(case: Case, poly: Any) -> tuple[np.ndarray, np.ndarray]:
    """DEM cell centres inside the outline, and the outline's vertices."""
    import shapely

    from fem_runout.terrain.dem import read_raster

    assert case.terrain.dem is not None
    raster = read_raster(case.resolve_input(case.terrain.dem), "terrain.dem",
                         case.terrain.fill_nodata)
    xc, yc = raster.centres()
    x0, y0, x1, y1 = poly.bounds
    gx, gy = np.meshgrid(xc[(xc >= x0) & (xc <= x1)], yc[(yc >= y0) & (yc <= y1)])
    inside = shapely.contains_xy(poly, gx, gy)
    ring = shapely.get_coordinates(poly)
    return np.concatenate([gx[inside], ring[:, 0]]), np.concatenate([gy[inside], ring[:, 1]])


def _outline(case: Case) -> dict[str, Any]:
    d = case.domain
    assert d.min_size is not None
    _require_file(case, "domain.outline", d.outline)
    shape = case_outline(case)
    poly = shape.geom
    _check_crs(case, shape.crs, "domain.outline")
    check_outline(poly, d.min_size, "domain.outline")
    refine = [_check_refine(case, poly, i, item) for i, item in enumerate(d.refine or ())]
    _check_release(case, poly, "domain.outline")
    if case.terrain.dem is not None:
        _check_dem(case, *_dem_points(case, poly), poly.bounds, "domain.outline")
    x0, y0, x1, y1 = (float(v) for v in poly.bounds)
    return {"extent": (x0, x1, y0, y1), "outline": _portable(case, d.outline),
            "refine": None if d.refine is None else tuple(refine)}


def _mesh_file(case: Case) -> dict[str, Any]:
    import shapely

    d = case.domain
    _require_file(case, "domain.mesh", d.mesh)
    assert d.mesh is not None
    mesh = read_msh(case.resolve_input(d.mesh), d.default_boundary)
    (x0, y0), (x1, y1) = mesh.nodes.min(axis=0), mesh.nodes.max(axis=0)
    _check_release(case, shapely.box(x0, y0, x1, y1), "domain.mesh")
    _check_dem(case, mesh.nodes[:, 0], mesh.nodes[:, 1], (x0, y0, x1, y1), "domain.mesh")
    size = mesh_quality(mesh.nodes, mesh.quads)["mean_edge"]
    return {"extent": (float(x0), float(x1), float(y0), float(y1)), "cell_size": size,
            "mesh": _portable(case, d.mesh)}


def resolve_domain(case: Case) -> Case:
    """Read and check ``domain.outline`` or ``domain.mesh``; fill ``domain.extent``.

    Idempotent; a rectangle is returned unchanged. Needs the run's CRS settled
    (``terrain.crs``) to compare the outline's and lines' CRS with it.

    Raises:
        CaseError: Missing or unreadable files; an invalid, too small or too narrow outline
            (or one with edges shorter than ``min_size``); an outline or mesh outside the DEM
            or on nodata; a refine line outside the outline; ``terrain`` refinement without
            a DEM, ``release`` refinement without release polygons; release polygons outside
            the domain; a mesh file that is not a planar mesh of convex first-order
            quadrilaterals with valid ``open``/``wall`` groups.
    """
    d = case.domain
    if d.kind == "rectangle":
        return case
    update = _outline(case) if d.kind == "outline" else _mesh_file(case)
    return case.model_copy(update={"domain": d.model_copy(update=update)})

