"""The ``domain`` key: what is meshed (rectangle, outline or mesh file) and its boundary.

Three kinds of domain (:attr:`DomainSpec.kind`):

- ``rectangle``: ``extent``/``window`` and ``cells``/``cell_size``, uniform squares (the fast
  path, :mod:`fem_runout.mesh`);
- ``outline``: a polygon (file or inline coordinates) meshed by gmsh with quadrilaterals of
  size ``min_size`` … ``cell_size``, graded by the ``refine`` fields (:mod:`fem_runout.meshing`);
- ``file``: the user's own gmsh ``.msh`` file of first-order quadrilaterals (``mesh``).

The files are read and the geometry checked when the case is loaded
(:func:`fem_runout.meshing.resolve.resolve_domain`); this module checks the case text only.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    BeforeValidator,
    Field,
    SerializerFunctionWrapHandler,
    model_serializer,
    model_validator,
)

from fem_runout.config.geo import FilePath, parse_window
from fem_runout.config.types import Real, SpecError, StrictSpec, is_number

__all__ = [
    "REFINE_KEYS",
    "SIDES",
    "BoundaryKind",
    "BoundarySides",
    "DomainKind",
    "DomainSpec",
    "RefineSpec",
]


Box = tuple[float, float, float, float]
Points = tuple[tuple[float, float], ...]

SIDES: tuple[str, ...] = ("left", "right", "bottom", "top")
BoundaryKind = Literal["open", "wall"]
DomainKind = Literal["rectangle", "outline", "file"]

# the keys each refine kind takes besides ``kind`` (the first ones are required)
REFINE_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "line": (("line", "size", "distance"), ()),
    "terrain": (("size",), ("tolerance",)),
    "release": (("size", "distance"), ()),
}
TERRAIN_TOLERANCE = 0.25  # default of ``refine[].tolerance`` [m]
_RECTANGLE_KEYS = ("extent", "window", "cells")
# the keys only an outline takes
_OUTLINE_KEYS = ("min_size", "refine", "smoothing")
#: Default ``smoothing`` of an outline mesh (passes; docs/meshes.md, "The mesh's smoothing").
SMOOTHING_PASSES = 20


class BoundarySides(StrictSpec):
    """Boundary kind of each side of the rectangle: ``open`` (outflow) or ``wall`` (slip)."""

    left: BoundaryKind = "open"
    right: BoundaryKind = "open"
    bottom: BoundaryKind = "open"
    top: BoundaryKind = "open"


def _boundary(value: Any) -> Any:
    """Turn ``open``/``wall`` into the same kind on every side."""
    if isinstance(value, str):
        if value not in ("open", "wall"):
            raise SpecError(
                f"{value!r} is not a known boundary; allowed: open, wall, "
                "or a mapping of left/right/bottom/top to open/wall"
            )
        return dict.fromkeys(SIDES, value)
    return value


def _cells(value: Any) -> Any:
    if value is None:
        return value
    ok = isinstance(value, list | tuple) and len(value) == 2
    if not ok or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value):
        raise SpecError(f"must be two positive integers, got {value!r}")
    return tuple(value)


def _points(value: Any, least: int, what: str) -> Any:
    """Accept a file path or inline ``[[x, y], ...]`` coordinates (``least`` distinct points)."""
    if value is None or isinstance(value, str):
        return value if value is None or value.strip() else _fail_path(value, what)
    if not isinstance(value, list | tuple):
        return _fail_path(value, what)
    pts = []
    for p in value:
        ok = isinstance(p, list | tuple) and len(p) == 2 and all(map(is_number, p))
        if not ok or not all(math.isfinite(v) for v in p):
            raise SpecError(f"must be [x, y] pairs of finite numbers; got the point {p!r}")
        pts.append((float(p[0]), float(p[1])))
    if least >= 3 and len(pts) > 1 and pts[0] == pts[-1]:
        pts.pop()  # a closed ring: the last point repeats the first
    if len(set(pts)) < least:
        raise SpecError(f"{what} needs at least {least} distinct points [x, y], "
                        f"got {len(set(pts))}")
    return tuple(pts)


def _fail_path(value: Any, what: str) -> Any:
    raise SpecError(f"must be a file path (GeoJSON, Shapefile, GeoPackage) or {what} "
                    f"coordinates [[x, y], ...], got {value!r}")


def _outline(value: Any) -> Any:
    return _points(value, 3, "a polygon")


def _line(value: Any) -> Any:
    return _points(value, 2, "a line")


class RefineSpec(StrictSpec):
    """One size field of an outline mesh (``domain.refine[i]``), chosen by ``kind``.

    - ``line``: size ``size`` at the polyline ``line`` (a file or ``[[x, y], ...]``), growing
      linearly to ``cell_size`` at ``distance`` from it (gmsh Distance + Threshold fields);
    - ``terrain``: finer where the bed curves: the bilinear bed of a cell of size ``h``
      deviates from the DEM by about ``h² λ / 8`` (λ the largest absolute eigenvalue of the
      DEM's Hessian, smoothed over ``size``), so ``h = sqrt(8 tolerance / λ)``, clamped to
      ``[size, cell_size]``; needs ``terrain.dem``;
    - ``release``: size ``size`` in the release polygons, growing linearly to ``cell_size`` at
      ``distance`` from them.

    Attributes:
        kind: ``line``, ``terrain`` or ``release``.
        size: The finest size of this field [m], within ``[min_size, cell_size]``.
        distance: Distance over which the size grows to ``cell_size`` [m] (line, release).
        line: The polyline: file path or inline coordinates (line).
        tolerance: Allowed deviation of the bilinear bed from the DEM [m] (terrain, default
            0.25).
    """

    kind: Literal["line", "terrain", "release"]
    size: Real = Field(gt=0)
    distance: Real | None = Field(None, gt=0)
    line: Annotated[str | Points | None, BeforeValidator(_line)] = None
    tolerance: Real | None = Field(None, gt=0)

    @model_validator(mode="before")
    @classmethod
    def _fill_tolerance(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("kind") == "terrain" and "tolerance" not in data:
            return {**data, "tolerance": TERRAIN_TOLERANCE}
        return data

    @model_validator(mode="after")
    def _keys_of_kind(self) -> RefineSpec:
        required, optional = REFINE_KEYS[self.kind]
        for key in ("distance", "line", "tolerance"):
            given = getattr(self, key) is not None
            if given and key not in required + optional:
                raise SpecError(f"not used by kind '{self.kind}' (it takes "
                                f"{', '.join(required + optional)})", key)
            if not given and key in required:
                raise SpecError(f"required key is missing (kind '{self.kind}' takes "
                                f"{', '.join(required + optional)})", key)
        return self


def _refine(value: Any) -> Any:
    if value is None:
        return value
    if not isinstance(value, list | tuple):
        raise SpecError("must be a list of size fields such as "
                        "{kind: line, line: <file>, size: <m>, distance: <m>}, got "
                        f"{value!r}")
    return tuple(value)


class DomainSpec(StrictSpec):
    """The meshed area and its boundary conditions.

    A rectangle (``extent``/``window`` with ``cells``/``cell_size``: uniform squares), a polygon
    ``outline`` meshed by gmsh with quadrilaterals (``cell_size``, ``min_size``, ``refine``),
    or the user's gmsh ``mesh`` file. With ``terrain.dem`` the rectangle's extent defaults to
    the DEM's (``window`` picks a part of it) and the cell size to the DEM resolution. For an
    outline or a mesh file ``extent`` is filled with their bounding box when the case is
    loaded (and ``cell_size`` of a mesh file with its mean edge length).

    Attributes:
        extent: ``(xmin, xmax, ymin, ymax)`` [m].
        window: Part of the DEM to simulate, ``(xmin, xmax, ymin, ymax)`` [m] (DEM only).
        cells: Number of cells along x and y (or ``None`` when ``cell_size`` is given).
        cell_size: Target cell size [m]; the largest cell size of an outline mesh.
        boundary: Kind of each side; for an outline or a mesh file, one kind (every side the
            same) used for the boundary edges not in a physical group ``open``/``wall``.
        outline: Polygon file or inline ``[[x, y], ...]`` coordinates (outline only).
        mesh: gmsh ``.msh`` file of first-order quadrilaterals (file only).
        min_size: Smallest cell size of an outline mesh [m] (default ``cell_size / 4``).
        refine: Size fields of an outline mesh (:class:`RefineSpec`).
        smoothing: Size-equalising passes over an outline mesh's interior nodes
            (:mod:`fem_runout.meshing.smoothing`; default 20, 0: gmsh's mesh as it is).
    """

    extent: Annotated[Box | None, BeforeValidator(parse_window)] = None
    window: Annotated[Box | None, BeforeValidator(parse_window)] = None
    cells: Annotated[tuple[int, int] | None, BeforeValidator(_cells)] = None
    cell_size: Real | None = Field(None, gt=0)
    boundary: Annotated[BoundarySides, BeforeValidator(_boundary)] = BoundarySides()
    outline: Annotated[str | Points | None, BeforeValidator(_outline)] = None
    mesh: FilePath | None = None
    min_size: Real | None = Field(None, gt=0)
    refine: Annotated[tuple[RefineSpec, ...] | None, BeforeValidator(_refine)] = None
    smoothing: int | None = Field(None, ge=0, le=200)

    @model_validator(mode="before")
    @classmethod
    def _check_kind_keys(cls, data: Any) -> Any:
        """Refuse keys of another kind; fill ``min_size`` of an outline."""
        if not isinstance(data, dict):
            return data
        given = [k for k in ("outline", "mesh") if data.get(k) is not None]
        if len(given) == 2:
            raise SpecError("give either outline or mesh, not both", "mesh")
        if not given:
            for key in _OUTLINE_KEYS:
                if data.get(key) is not None:
                    raise SpecError("only used with domain.outline", key)
            return data
        kind = given[0]
        others = (*_RECTANGLE_KEYS, *(("cell_size", *_OUTLINE_KEYS) if kind == "mesh" else ()))
        for key in others:
            if data.get(key) is not None:
                raise SpecError(f"not used with domain.{kind} (the {kind} sets the domain)", key)
        if isinstance(data.get("boundary"), dict):
            raise SpecError(f"must be open or wall with domain.{kind}: the sides left, right, "
                            "bottom, top only exist for the rectangle", "boundary")
        size = data.get("cell_size")
        if kind == "outline" and data.get("min_size") is None and is_number(size) and size > 0:
            data = {**data, "min_size": size / 4}
        if kind == "outline" and data.get("smoothing") is None:
            data = {**data, "smoothing": SMOOTHING_PASSES}
        return data

    @model_validator(mode="after")
    def _one_resolution(self) -> DomainSpec:
        if self.kind == "outline":
            return self._check_sizes()
        if self.kind == "file":
            return self
        if self.cells is not None and self.cell_size is not None:
            raise SpecError("give exactly one of cells: [nx, ny] or cell_size: <m>")
        if self.extent is not None and self.window is not None:
            raise SpecError("give either extent or window, not both", "window")
        return self

    def _check_sizes(self) -> DomainSpec:
        """``min_size <= size <= cell_size`` for every refine field."""
        if self.cell_size is None:
            raise SpecError("required key is missing (the largest cell size of the outline "
                            "mesh, m)", "cell_size")
        hi, lo = self.cell_size, self.min_size or self.cell_size / 4
        if lo > hi:
            raise SpecError(f"must be <= cell_size ({hi:g}), got {lo:g}", "min_size")
        for i, item in enumerate(self.refine or ()):
            if not lo <= item.size <= hi:
                raise SpecError(f"must be >= min_size ({lo:g}) and <= cell_size ({hi:g}), got "
                                f"{item.size:g}", f"refine[{i}].size")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler: SerializerFunctionWrapHandler) -> Any:
        """Leave out what loading fills in for an outline or a mesh file (so it reloads)."""
        data = handler(self)
        if self.kind == "rectangle" or not isinstance(data, dict):
            return data
        data.pop("extent", None)
        if self.kind == "file":
            data.pop("cell_size", None)
        if "boundary" in data:
            data["boundary"] = self.boundary.left
        return data

    @property
    def kind(self) -> DomainKind:
        """``rectangle`` (extent and cells), ``outline`` (a polygon) or ``file`` (a .msh)."""
        if self.outline is not None:
            return "outline"
        if self.mesh is not None:
            return "file"
        return "rectangle"

    @property
    def resolved_cells(self) -> tuple[int, int]:
        """Number of cells ``(nx, ny)``, from ``cells`` or from ``cell_size`` (at least 1).

        For an outline or a mesh file: of the bounding box at ``cell_size`` (indicative only).
        """
        if self.cells is not None:
            return self.cells
        assert self.cell_size is not None and self.extent is not None, "case not resolved"
        xmin, xmax, ymin, ymax = self.extent
        return (
            max(1, round((xmax - xmin) / self.cell_size)),
            max(1, round((ymax - ymin) / self.cell_size)),
        )

    @property
    def sides(self) -> dict[str, BoundaryKind]:
        """Boundary kind by side name: ``left``, ``right``, ``bottom``, ``top``."""
        return {side: getattr(self.boundary, side) for side in SIDES}

    @property
    def default_boundary(self) -> BoundaryKind:
        """The boundary kind of an outline, or of the untagged edges of a mesh file."""
        return self.boundary.left
