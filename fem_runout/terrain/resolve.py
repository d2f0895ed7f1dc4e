"""Complete a case that uses real terrain when it is loaded (before anything runs).

With ``terrain.dem`` the domain extent and cell size are filled from the DEM (nodes on DEM cell
centres), the CRS is settled (DEM, else ``terrain.crs``, else the release's with a warning)
and checked against the release files, and nodata inside the domain is refused (or filled).
Every problem is a :class:`~fem_runout.errors.CaseError` naming the key, so the command line
exits with code 2 before writing anything.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.terrain.dem import Raster, read_raster
from fem_runout.terrain.nodes import elevation_at
from fem_runout.terrain.paths import DATA_ENV, DATA_PLACEHOLDER, data_folder
from fem_runout.terrain.release import feature_thickness, read_polygons

if TYPE_CHECKING:  # fem_runout.config.loader imports this module (lazily): no import back
    from fem_runout.config import Case

__all__ = ["resolve_terrain", "same_crs"]

_TOL = 1e-9


def same_crs(a: object, b: object) -> bool:
    """Whether two CRS (rasterio CRS, EPSG code text, WKT) are the same."""
    from rasterio.crs import CRS

    ca, cb = CRS.from_user_input(a), CRS.from_user_input(b)
    if ca == cb:
        return True
    ea, eb = ca.to_epsg(), cb.to_epsg()
    return ea is not None and ea == eb


def _crs_text(crs: object, key: str) -> str:
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    try:
        return CRS.from_user_input(crs).to_string()
    except CRSError as exc:
        raise CaseError(f"{key}: {crs!r} is not a known CRS ({exc})") from None


def _release_crs(case: Case) -> list[tuple[str, str | None]]:
    """``(key, crs text or None)`` of every release file; checks that the files are usable."""
    out: list[tuple[str, str | None]] = []
    for i, item in enumerate(case.initial.release or ()):
        key = f"initial.release[{i}]"
        if item.raster is not None:
            raster = read_raster(case.resolve_input(item.raster), f"{key}.raster")
            crs = None if raster.crs is None else raster.crs.to_string()
            out.append((f"{key}.raster", crs))
        else:
            polys = read_polygons(case.resolve_input(item.polygon or ""), f"{key}.polygon")
            feature_thickness(polys, item.thickness, key)
            out.append((f"{key}.polygon", polys.crs))
    return out


def _settle_crs(case: Case, raster: Raster, releases: list[tuple[str, str | None]]) -> str | None:
    """Return the CRS of the run: the DEM's, else ``terrain.crs``, else the release's (warning)."""
    given = case.terrain.crs
    crs = None if raster.crs is None else raster.crs.to_string()
    if given is not None:
        given = _crs_text(given, "terrain.crs")
        if crs is not None and not same_crs(crs, given):
            raise CaseError(f"terrain.crs: {given} differs from the CRS of the DEM, {crs}")
        crs = crs or given
    if crs is None:
        found = [(key, c) for key, c in releases if c is not None]
        if found:
            key, crs = found[0]
            warnings.warn(f"terrain.dem '{raster.path.name}' has no CRS; using {crs} of {key} "
                          "(set terrain.crs to state it)", stacklevel=3)
    for key, c in releases:
        if crs is not None and c is not None and not same_crs(c, crs):
            raise CaseError(f"{key}: its CRS {c} differs from the DEM's {crs}; reproject it")
    return crs


def _span(lo: float, hi: float, c0: float, step: float, n: int, key: str) -> tuple[int, int]:
    """Return the indices of the first and last cell centre inside ``[lo, hi]``."""
    i0 = max(0, math.ceil((lo - c0) / step - _TOL))
    i1 = min(n - 1, math.floor((hi - c0) / step + _TOL))
    if i1 <= i0:
        raise CaseError(f"{key}: {lo:g}..{hi:g} holds fewer than two DEM cell centres")
    return i0, i1


def _grid(case: Case, raster: Raster) -> tuple[tuple[float, float, float, float], float | None]:
    """Extent on DEM cell centres and the cell size (None when ``cells`` is given)."""
    d = case.domain
    dx, dy = raster.res
    xc, yc = raster.centres()
    x0, y0 = float(xc[0]), float(yc[-1])  # south-west cell centre
    rows, cols = raster.shape
    key = "domain.window" if d.window is not None else "domain.extent"
    box = d.window or d.extent or (x0, float(xc[-1]), y0, float(yc[0]))
    ix0, ix1 = _span(box[0], box[1], x0, dx, cols, key)
    iy0, iy1 = _span(box[2], box[3], y0, dy, rows, key)
    size = d.cell_size if d.cells is None else None
    if d.cells is None and size is None:
        size = dx
    kx = ky = 1
    if size is not None:
        k = round(size / dx)
        if k >= 1 and abs(size / dx - k) < 0.01 and abs(dx - dy) < 1e-6 * dx:
            kx = ky = k  # within 1 % of a multiple of the resolution: nodes on cell centres
            size = k * dx
    ix1 = ix0 + (ix1 - ix0) // kx * kx
    iy1 = iy0 + (iy1 - iy0) // ky * ky
    return (x0 + ix0 * dx, x0 + ix1 * dx, y0 + iy0 * dy, y0 + iy1 * dy), size


def _check_nodata(case: Case) -> None:
    """Sample the DEM at every node of the mesh (raises CaseError on nodata)."""
    xmin, xmax, ymin, ymax = case.domain.extent or (0, 0, 0, 0)
    nx, ny = case.domain.resolved_cells
    x, y = np.meshgrid(np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1))
    elevation_at(case, x.ravel(), y.ravel())


def _check_files(case: Case) -> None:
    """Refuse a missing input file; for ``${FEM_RUNOUT_DATA}`` paths say where data come from."""
    paths = [("terrain.dem", case.terrain.dem)]
    for i, item in enumerate(case.initial.release or ()):
        paths += [(f"initial.release[{i}].polygon", item.polygon),
                  (f"initial.release[{i}].raster", item.raster)]
    for key, text in paths:
        if text is None or case.resolve_input(text).is_file():
            continue
        hint = ""
        if DATA_PLACEHOLDER in text:
            hint = (f"; {DATA_ENV} names the data folder (now '{data_folder()}', default "
                    "../shared/data from the project root); the avaKot files come from the "
                    "AvaFrame repository, github.com/avaframe/AvaFrame, "
                    "avaframe/data/avaKot/Inputs (see docs/real_terrain.md)")
        raise CaseError(f"{key}: file '{case.resolve_input(text)}' does not exist{hint}")


def _resolve_domain(case: Case) -> Case:
    """Read and check an outline or a mesh file, fill the extent (meshing.resolve)."""
    if case.domain.kind == "rectangle":
        return case
    from fem_runout.meshing.resolve import resolve_domain

    return resolve_domain(case)


def resolve_terrain(case: Case) -> Case:
    """Fill and check the real-terrain parts of a case (idempotent; reads the input files).

    Raises:
        CaseError: Missing or unreadable files, nodata in the domain, CRS mismatch, a window
            outside the DEM; for an outline or a mesh file, what
            :func:`fem_runout.meshing.resolve.resolve_domain` refuses.
    """
    _check_files(case)
    releases = _release_crs(case)
    if case.terrain.dem is None:
        return _resolve_domain(case)
    t = case.terrain
    raster = read_raster(case.resolve_input(t.dem), "terrain.dem", t.fill_nodata)
    crs = _settle_crs(case, raster, releases)
    if case.domain.kind != "rectangle":
        terrain = t.model_copy(update={"crs": crs})
        return _resolve_domain(case.model_copy(update={"terrain": terrain}))
    extent, size = _grid(case, raster)
    update = {"extent": extent, "window": None}
    if size is not None:
        update["cell_size"] = size
    resolved = case.model_copy(update={
        "domain": case.domain.model_copy(update=update),
        "terrain": t.model_copy(update={"crs": crs}),
    })
    _check_nodata(resolved)
    return resolved
