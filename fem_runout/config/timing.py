"""The ``time`` key: end time (or ``auto``: stop at rest), CFL number and step limits."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, model_validator

from fem_runout.config.types import Int, Real, SpecError, StrictSpec

__all__ = ["TimeSpec"]


def _end(value: Any) -> Any:
    if value == "auto":
        return value
    if isinstance(value, str):
        raise SpecError(f"must be a number or auto, got {value!r}")
    return value


class TimeSpec(StrictSpec):
    """End time [s], CFL number, optional step limits and the rest criterion of ``end: auto``.

    With ``end: auto`` the run stops when the largest speed (over nodes deeper than
    ``output.front_threshold``) has stayed below ``rest_speed`` for ``rest_duration`` seconds,
    or (with ``rest_energy``) the kinetic energy has stayed below ``rest_energy`` times its peak
    for ``rest_duration`` seconds, or at ``max`` seconds.
    """

    end: Annotated[Real | Literal["auto"], BeforeValidator(_end)]
    cfl: Real = Field(0.9, gt=0, le=1)
    max_steps: Int | None = Field(None, gt=0)
    dt_max: Real | None = Field(None, gt=0)
    max: Real | None = Field(None, gt=0)
    rest_speed: Real = Field(0.01, gt=0)
    rest_duration: Real = Field(5.0, ge=0)
    rest_energy: Real | None = Field(None, gt=0, lt=1)

    @model_validator(mode="after")
    def _auto_needs_max(self) -> TimeSpec:
        if self.end == "auto" and self.max is None:
            raise SpecError("required with end: auto (the longest run, in seconds)", "max")
        if self.end != "auto":
            if not self.end > 0:
                raise SpecError(f"must be > 0 or auto, got {self.end:g}", "end")
            for key in ("max", "rest_energy"):
                if getattr(self, key) is not None:
                    raise SpecError("only used with end: auto", key)
        return self

    @property
    def auto(self) -> bool:
        """Whether the run stops when the flow comes to rest."""
        return self.end == "auto"

    @property
    def end_time(self) -> float:
        """The latest end time [s]: ``end``, or ``max`` with ``end: auto``."""
        if self.end == "auto":
            assert self.max is not None
            return float(self.max)
        return float(self.end)
