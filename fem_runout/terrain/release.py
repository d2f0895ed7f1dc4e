"""Release areas: polygons (Shapefile, GeoJSON) read with pyogrio, turned into nodal depths.

A polygon's depth at a node is ``thickness × (area of the node's dual cell inside the
polygon) / (dual cell area)``. The dual cell of a Q1 node on a uniform grid has exactly the
node's lumped mass as area, so ``Σ M_i h_i`` equals ``Σ thickness × polygon area`` (inside the
domain) up to round-off.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fem_runout.errors import CaseError

__all__ = ["Polygons", "polygon_depth", "read_polygons", "vector_crs"]


@dataclass(frozen=True, eq=False)
class Polygons:
    """Polygon features of a vector file.

    Attributes:
        geoms: Shapely (multi)polygons, one per feature.
        thickness: The features' ``thickness`` attribute, or None if the file has none.
        crs: The file's CRS as text (``EPSG:31287``, WKT), or None.
        path: The file.
    """

    geoms: np.ndarray
    thickness: np.ndarray | None
    crs: str | None
    path: Path


def read_polygons(path: str | Path, key: str) -> Polygons:
    """Read the polygon features of a vector file (cached by path and modification time).

    Raises:
        CaseError: If the file is missing, unreadable, empty or holds non-polygons.
    """
    p = Path(path)
    if not p.is_file():
        raise CaseError(f"{key}: file '{p}' does not exist")
    return _read_cached(str(p.resolve()), p.stat().st_mtime_ns, key)


@functools.lru_cache(maxsize=8)
def _read_cached(path: str, mtime: int, key: str) -> Polygons:
    import pyogrio
    import shapely

    try:
        meta, _, wkb, fields = pyogrio.raw.read(path)
    except (pyogrio.errors.DataSourceError, pyogrio.errors.DataLayerError, OSError) as exc:
        raise CaseError(f"{key}: cannot read '{path}': {exc}") from None
    geoms = shapely.from_wkb(wkb) if wkb is not None else np.empty(0, dtype=object)
    kinds = set(shapely.get_type_id(geoms).tolist()) if len(geoms) else set()
    if not len(geoms) or not kinds <= {3, 6}:  # Polygon, MultiPolygon
        raise CaseError(f"{key}: '{path}' must hold polygon features")
    geoms = shapely.make_valid(geoms)
    names = [str(n).lower() for n in meta["fields"]]
    thickness = None
    if "thickness" in names:
        thickness = np.asarray(fields[names.index("thickness")], dtype=np.float64)
        if not (np.isfinite(thickness) & (thickness > 0)).all():
            raise CaseError(f"{key}: the thickness attribute of '{path}' must be > 0")
    return Polygons(geoms, thickness, meta.get("crs"), Path(path))


def vector_crs(path: str | Path, key: str) -> str | None:
    """Return the CRS of a polygon file, as text, or None."""
    return read_polygons(path, key).crs


def feature_thickness(polys: Polygons, given: float | None, key: str) -> np.ndarray:
    """Thickness of every feature: the case's value, else the ``thickness`` attribute.

    Raises:
        CaseError: If neither is available.
    """
    if given is not None:
        return np.full(len(polys.geoms), float(given))
    if polys.thickness is None:
        raise CaseError(f"{key}.thickness: required key is missing (the features of "
                        f"'{polys.path.name}' have no thickness attribute)")
    return polys.thickness


def polygon_depth(
    polys: Polygons, thickness: np.ndarray, x: np.ndarray, y: np.ndarray,
    spacing: tuple[float, float], extent: tuple[float, float, float, float],
) -> np.ndarray:
    """Depth at nodes from polygons: thickness × covered fraction of each node's dual cell.

    Args:
        polys: The polygons.
        thickness: Thickness of each feature [m].
        x: Node x.
        y: Node y.
        spacing: Grid spacing ``(dx, dy)``.
        extent: Domain ``(xmin, xmax, ymin, ymax)``; dual cells are clipped to it.

    Returns:
        Depth per node (overlapping features add up).
    """
    import shapely

    dx, dy = spacing
    xmin, xmax, ymin, ymax = extent
    x0, x1 = np.maximum(x - dx / 2, xmin), np.minimum(x + dx / 2, xmax)
    y0, y1 = np.maximum(y - dy / 2, ymin), np.minimum(y + dy / 2, ymax)
    area = (x1 - x0) * (y1 - y0)
    h = np.zeros(x.shape)
    for geom, t in zip(polys.geoms, thickness, strict=True):
        bx0, by0, bx1, by1 = shapely.bounds(geom)
        near = np.flatnonzero((x1 > bx0) & (x0 < bx1) & (y1 > by0) & (y0 < by1) & (area > 0))
        if not near.size:
            continue
        boxes = shapely.box(x0[near], y0[near], x1[near], y1[near])
        covered = shapely.area(shapely.intersection(boxes, geom))
        h[near] += t * covered / area[near]
    return h
