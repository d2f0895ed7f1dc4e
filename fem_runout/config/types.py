"""Strict field types of the case schema: numbers, integers, booleans and expressions.

Values are never coerced from strings ("9.81" is refused); each failure raises
:class:`SpecError`, which the loader turns into a message naming the key.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict

from fem_runout.config.expr import ExpressionError, check_expression

__all__ = ["Bool", "Expr", "Int", "Real", "SpecError", "StrictSpec", "is_number"]


class StrictSpec(BaseModel):
    """Base of every section of the case: unknown keys are refused, instances are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class SpecError(ValueError):
    """A check failed; ``key`` (if set) is the sub-key the problem is about."""

    def __init__(self, message: str, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


def is_number(value: Any) -> bool:
    """Tell whether ``value`` is an int or float (booleans are not numbers here)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def _real(value: Any) -> Any:
    """Accept finite real numbers only (no strings, no booleans)."""
    if value is None:
        return value
    if not is_number(value):
        raise SpecError(f"must be a number, got {value!r}")
    if not math.isfinite(value):
        raise SpecError(f"must be a finite number, got {value!r}")
    return float(value)


def _integer(value: Any) -> Any:
    """Accept integers only (no floats, strings or booleans)."""
    if value is None:
        return value
    if not isinstance(value, int) or isinstance(value, bool):
        raise SpecError(f"must be an integer, got {value!r}")
    return value


def _expression(value: Any) -> Any:
    """Accept an expression string (or a plain number) and check it."""
    if is_number(value):
        value = repr(value)
    if not isinstance(value, str):
        raise SpecError(f'must be an expression string such as "100 - x/3", got {value!r}')
    try:
        check_expression(value)
    except ExpressionError as exc:
        raise SpecError(str(exc)) from None
    return value


def _strict_bool(value: Any) -> Any:
    if not isinstance(value, bool):
        raise SpecError(f"must be true or false, got {value!r}")
    return value


Real = Annotated[float, BeforeValidator(_real)]
Int = Annotated[int, BeforeValidator(_integer)]
Expr = Annotated[str, BeforeValidator(_expression)]
Bool = Annotated[bool, BeforeValidator(_strict_bool)]
