"""Outline polygons and refine lines: read from a vector file or inline coordinates, checked.

Files are read with pyogrio (GeoJSON, Shapefile, GeoPackage, any OGR format); the first
feature is used. Every problem is a :class:`~fem_runout.errors.CaseError` naming the key.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.errors import CaseError

if TYPE_CHECKING:
    from fem_runout.config import Case

__all__ = ["Shape", "case_line", "case_outline", "check_outline", "read_shape", "release_union"]


@dataclass(frozen=True, eq=False)
class Shape:
    """A polygon or a line of the domain.

    Attributes:
        geom: Shapely Polygon (outline) or LineString (refine line).
        crs: The file's CRS as text, or None (inline coordinates, or a file without one).
    """

    geom: Any
    crs: str | None


def read_shape(value: str | tuple[tuple[float, float], ...], path: Path | None, kind: str,
               key: str) -> Shape:
    """Return the polygon (``kind="polygon"``) or line (``"line"``) of a case value.

    Args:
        value: Inline coordinates, or the file path as written in the case.
        path: The resolved file (None for inline coordinates).
        kind: ``polygon`` or ``line``.
        key: Case key named in errors.

    Raises:
        CaseError: Unreadable file, no feature of that kind, several parts, an invalid
            (self-intersecting) polygon.
    """
    import shapely

    if path is None:
        coords = np.asarray(value, dtype=np.float64)
        geom = shapely.Polygon(coords) if kind == "polygon" else shapely.LineString(coords)
        shape = Shape(geom, None)
    else:
        if not path.is_file():
            raise CaseError(f"{key}: file '{path}' does not exist")
        shape = _read_cached(str(path.resolve()), path.stat().st_mtime_ns, kind, key)
    if kind == "polygon":
        _check_valid(shape.geom, key)
    return shape


@functools.lru_cache(maxsize=16)
def _read_cached(path: str, mtime: int, kind: str, key: str) -> Shape:
    import pyogrio
    import shapely

    try:
        meta, _, wkb, _ = pyogrio.raw.read(path)
    except (pyogrio.errors.DataSourceError, pyogrio.errors.DataLayerError, OSError) as exc:
        raise CaseError(f"{key}: cannot read '{path}': {exc}") from None
    geoms = shapely.from_wkb(wkb) if wkb is not None else np.empty(0, dtype=object)
    wanted = ("Polygon", "MultiPolygon") if kind == "polygon" else ("LineString",
                                                                    "MultiLineString")
    found = [g for g in geoms if g is not None and g.geom_type in wanted and not g.is_empty]
    if not found:
        raise CaseError(f"{key}: '{path}' holds no {kind} feature; allowed: a file whose first "
                        f"{kind} feature is the {'outline' if kind == 'polygon' else 'line'}")
    geom = found[0]
    if geom.geom_type.startswith("Multi"):
        if kind == "line":
            geom = shapely.line_merge(geom)
        if len(getattr(geom, "geoms", [geom])) != 1:
            raise CaseError(f"{key}: the first {kind} feature of '{path}' has "
                            f"{len(geom.geoms)} parts; allowed: one connected {kind}")
        geom = getattr(geom, "geoms", [geom])[0]
    geom = shapely.force_2d(geom)
    return Shape(geom, meta.get("crs"))


def _check_valid(poly: Any, key: str) -> None:
    """Refuse a polygon that is not simple (self-intersecting, too few points)."""
    from shapely.validation import explain_validity

    ring = np.asarray(poly.exterior.coords)[:-1]
    if len(np.unique(ring, axis=0)) < 3:
        raise CaseError(f"{key}: needs at least 3 distinct points, got "
                        f"{len(np.unique(ring, axis=0))}")
    if not poly.is_valid or poly.area <= 0:
        raise CaseError(f"{key}: is not a valid polygon: {explain_validity(poly)}; allowed: a "
                        "simple polygon (no self-intersection, no repeated ring)")


def _rings(poly: Any) -> list[np.ndarray]:
    return [np.asarray(r.coords)[:-1, :2] for r in (poly.exterior, *poly.interiors)]


def check_outline(poly: Any, min_size: float, key: str) -> None:
    """Refuse an outline too small or too narrow for ``min_size``, or with too short edges.

    Every outline vertex becomes a mesh node, so an edge shorter than ``min_size`` would make
    cells smaller than ``min_size``; a part narrower than ``2 min_size`` (the polygon shrunk
    by ``min_size`` is empty or falls apart) cannot hold two cells across.
    """
    for ring in _rings(poly):
        length = np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1)
        if length.min() < min_size * (1 - 1e-9):
            i = int(np.argmin(length))
            (x0, y0), (x1, y1) = ring[i], ring[(i + 1) % len(ring)]
            raise CaseError(
                f"{key}: the edge ({x0:.6g}, {y0:.6g})-({x1:.6g}, {y1:.6g}) is "
                f"{length[i]:.3g} m long, shorter than domain.min_size ({min_size:g} m); every "
                "outline vertex is a mesh node: simplify the outline (vertices at least "
                "min_size apart) or lower domain.min_size")
    core = poly.buffer(-min_size)
    if core.is_empty:
        raise CaseError(f"{key}: is too small for domain.min_size = {min_size:g} m: it is "
                        f"nowhere wider than 2 x min_size (area {poly.area:.6g} m²); allowed: "
                        "an outline at least 2 x min_size wide")
    if core.geom_type != "Polygon":
        raise CaseError(f"{key}: is narrower than 2 x domain.min_size = {2 * min_size:g} m "
                        "somewhere (the outline shrunk by min_size falls apart into "
                        f"{len(core.geoms)} pieces); widen it or lower domain.min_size")


def _path(case: Case, value: Any) -> Path | None:
    return case.resolve_input(value) if isinstance(value, str) else None


def case_outline(case: Case) -> Shape:
    """Return the polygon of ``domain.outline`` (file or inline)."""
    value = case.domain.outline
    return read_shape(value, _path(case, value), "polygon", "domain.outline")


def case_line(case: Case, i: int) -> Shape:
    """Return the line of ``domain.refine[i]`` (kind ``line``)."""
    value = (case.domain.refine or ())[i].line
    return read_shape(value, _path(case, value), "line", f"domain.refine[{i}].line")


def release_union(case: Case) -> Any | None:
    """Union of the release polygons (``initial.release[*].polygon``), or None."""
    import shapely

    from fem_runout.terrain.release import read_polygons

    geoms = []
    for i, item in enumerate(case.initial.release or ()):
        if item.polygon is not None:
            polys = read_polygons(case.resolve_input(item.polygon), f"initial.release[{i}].polygon")
            geoms.extend(polys.geoms)
    return shapely.union_all(geoms) if geoms else None
