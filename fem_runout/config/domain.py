"""The ``domain`` key: the rectangle, its structured mesh and its boundary conditions."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, model_validator

from fem_runout.config.geo import parse_window
from fem_runout.config.types import Real, SpecError, StrictSpec

__all__ = ["SIDES", "BoundaryKind", "BoundarySides", "DomainSpec"]


Box = tuple[float, float, float, float]


SIDES: tuple[str, ...] = ("left", "right", "bottom", "top")
BoundaryKind = Literal["open", "wall"]


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


class DomainSpec(StrictSpec):
    """The rectangle, its structured mesh and its boundary conditions.

    With ``terrain.dem`` the extent defaults to the DEM's (``window`` picks a part of it) and
    the cell size to the DEM resolution; both are filled in when the case is loaded, with the
    nodes on DEM cell centres.

    Attributes:
        extent: ``(xmin, xmax, ymin, ymax)`` [m].
        window: Part of the DEM to simulate, ``(xmin, xmax, ymin, ymax)`` [m] (DEM only).
        cells: Number of cells along x and y (or ``None`` when ``cell_size`` is given).
        cell_size: Target cell size [m] (or ``None`` when ``cells`` is given).
        boundary: Kind of each side.
    """

    extent: Annotated[Box | None, BeforeValidator(parse_window)] = None
    window: Annotated[Box | None, BeforeValidator(parse_window)] = None
    cells: Annotated[tuple[int, int] | None, BeforeValidator(_cells)] = None
    cell_size: Real | None = Field(None, gt=0)
    boundary: Annotated[BoundarySides, BeforeValidator(_boundary)] = BoundarySides()

    @model_validator(mode="after")
    def _one_resolution(self) -> DomainSpec:
        if self.cells is not None and self.cell_size is not None:
            raise SpecError("give exactly one of cells: [nx, ny] or cell_size: <m>")
        if self.extent is not None and self.window is not None:
            raise SpecError("give either extent or window, not both", "window")
        return self

    @property
    def resolved_cells(self) -> tuple[int, int]:
        """Number of cells ``(nx, ny)``, from ``cells`` or from ``cell_size`` (at least 1)."""
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
