"""A small, safe expression language for fields given in case files.

Case files describe terrain, initial depth and velocity as formulas of the
coordinates, e.g. ``"100 - x/3"`` or ``"where(x <= 20, x/3, 0)"``. The source is
parsed with :func:`ast.parse` and every node is checked against a whitelist;
evaluation walks the checked tree with numpy. Nothing is ever passed to
``eval``, ``exec`` or ``compile``.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable
from typing import Any

import numpy as np

from fem_runout.errors import CaseError

__all__ = [
    "ALLOWED_FUNCTIONS",
    "ALLOWED_NAMES",
    "Expression",
    "ExpressionError",
    "check_expression",
    "compile_expression",
]

# name -> (numpy function, number of positional arguments)
_FUNCTIONS: dict[str, tuple[Callable[..., Any], int]] = {
    "abs": (np.abs, 1),
    "arctan2": (np.arctan2, 2),
    "ceil": (np.ceil, 1),
    "clip": (np.clip, 3),
    "cos": (np.cos, 1),
    "exp": (np.exp, 1),
    "floor": (np.floor, 1),
    "hypot": (np.hypot, 2),
    "log": (np.log, 1),
    "maximum": (np.maximum, 2),
    "minimum": (np.minimum, 2),
    "sin": (np.sin, 1),
    "sqrt": (np.sqrt, 1),
    "tan": (np.tan, 1),
    "tanh": (np.tanh, 1),
    "where": (np.where, 3),
}
_CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}
_VARIABLES: tuple[str, ...] = ("x", "y")

ALLOWED_FUNCTIONS: tuple[str, ...] = tuple(sorted(_FUNCTIONS))
"""Functions an expression may call, by plain name with positional arguments."""
ALLOWED_NAMES: tuple[str, ...] = (*_VARIABLES, *_CONSTANTS)
"""Names an expression may use: the coordinates and two constants."""

_BINARY: dict[type[ast.operator], Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: np.power,
    ast.Mod: np.mod,
}
_UNARY: dict[type[ast.unaryop], Callable[[Any], Any]] = {
    ast.UAdd: operator.pos,
    ast.USub: operator.neg,
    ast.Not: np.logical_not,
}
_COMPARE: dict[type[ast.cmpop], Callable[[Any, Any], Any]] = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}
_BOOL: dict[type[ast.boolop], Callable[[Any, Any], Any]] = {
    ast.And: np.logical_and,
    ast.Or: np.logical_or,
}
_MAX_LENGTH = 10_000
_ALLOWED_HINT = (
    f"(allowed functions: {', '.join(ALLOWED_FUNCTIONS)}; names: {', '.join(ALLOWED_NAMES)})"
)


class ExpressionError(ValueError):
    """An expression was rejected; the message does not name the key."""


def _describe(node: ast.AST) -> str:
    """Say in a few words what a rejected node is."""
    match node:
        case ast.Constant(value=bool()):
            return f"boolean constant {node.value!r} (use 1 or 0)"
        case ast.Constant():
            return f"constant {node.value!r} (only numbers are allowed)"
        case ast.Attribute(attr=attr):
            return f"attribute access '.{attr}'"
        case ast.Subscript():
            return "subscript '[...]'"
        case ast.Lambda():
            return "lambda"
        case ast.ListComp() | ast.SetComp() | ast.DictComp() | ast.GeneratorExp():
            return "comprehension"
        case ast.JoinedStr() | ast.FormattedValue():
            return "f-string"
        case ast.NamedExpr():
            return "assignment expression ':='"
        case ast.Starred():
            return "starred argument"
        case ast.List() | ast.Tuple() | ast.Set() | ast.Dict():
            return f"{type(node).__name__.lower()} display"
        case ast.IfExp():
            return "conditional 'a if c else b' (use where(c, a, b))"
    return f"{type(node).__name__} syntax"


def _check_call(node: ast.Call, check: Callable[[ast.AST], None]) -> None:
    """Check a call: a whitelisted function, positional arguments, right count."""
    if not isinstance(node.func, ast.Name):
        raise ExpressionError(f"call of {_describe(node.func)}")
    name = node.func.id
    if name not in _FUNCTIONS:
        raise ExpressionError(f"call of '{name}'")
    if node.keywords:
        raise ExpressionError(f"keyword argument in call of '{name}' (use positional arguments)")
    nargs = _FUNCTIONS[name][1]
    if len(node.args) != nargs:
        raise ExpressionError(
            f"'{name}' takes {nargs} argument{'s' if nargs > 1 else ''}, got {len(node.args)}"
        )
    for arg in node.args:
        check(arg)


def _check(node: ast.AST) -> None:
    """Raise ExpressionError unless ``node`` and all its children are allowed."""
    match node:
        case ast.Constant(value=value) if type(value) in (int, float):
            return
        case ast.Name(id=name):
            if name not in ALLOWED_NAMES:
                raise ExpressionError(f"unknown name '{name}'")
            return
        case ast.UnaryOp(op=op, operand=operand) if type(op) in _UNARY:
            _check(operand)
            return
        case ast.BinOp(op=op, left=left, right=right) if type(op) in _BINARY:
            _check(left)
            _check(right)
            return
        case ast.BoolOp(op=op, values=values) if type(op) in _BOOL:
            for value in values:
                _check(value)
            return
        case ast.Compare(left=left, ops=ops, comparators=comparators):
            bad = [op for op in ops if type(op) not in _COMPARE]
            if bad:
                raise ExpressionError(f"comparison operator {type(bad[0]).__name__}")
            for child in (left, *comparators):
                _check(child)
            return
        case ast.Call():
            _check_call(node, _check)
            return
        case ast.UnaryOp(op=op) | ast.BinOp(op=op):
            raise ExpressionError(f"operator {type(op).__name__}")
    raise ExpressionError(_describe(node))


def check_expression(src: str) -> ast.Expression:
    """Parse and check an expression without naming a key.

    Args:
        src: The expression source, e.g. ``"100 - x/3"``.

    Returns:
        The checked syntax tree.

    Raises:
        ExpressionError: If the source does not parse or uses anything not allowed; the
            message starts with ``expression "<src>"``.
    """
    if not isinstance(src, str):
        raise ExpressionError(f"expression must be a string or a number, got {src!r}")
    text = src.strip()
    if not text:
        raise ExpressionError("expression is empty")
    if len(text) > _MAX_LENGTH:
        raise ExpressionError(f"expression is longer than {_MAX_LENGTH} characters")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else ""
        raise ExpressionError(f'expression "{src}" cannot parse: {exc.msg}{where}') from None
    except (RecursionError, MemoryError):
        raise ExpressionError(f'expression "{src}" cannot parse: nested too deeply') from None
    try:
        _check(tree.body)
    except ExpressionError as exc:
        raise ExpressionError(f'expression "{src}" is not allowed: {exc} {_ALLOWED_HINT}') from None
    except RecursionError:
        raise ExpressionError(f'expression "{src}" is not allowed: nested too deeply') from None
    return tree


def _evaluate(node: ast.AST, env: dict[str, Any]) -> Any:
    """Evaluate a checked node with numpy."""
    match node:
        case ast.Constant(value=value):
            return np.float64(value)
        case ast.Name(id=name):
            return env[name]
        case ast.UnaryOp(op=op, operand=operand):
            return _UNARY[type(op)](_evaluate(operand, env))
        case ast.BinOp(op=op, left=left, right=right):
            return _BINARY[type(op)](_evaluate(left, env), _evaluate(right, env))
        case ast.BoolOp(op=op, values=values):
            result = _evaluate(values[0], env)
            for value in values[1:]:
                result = _BOOL[type(op)](result, _evaluate(value, env))
            return result
        case ast.Compare(left=left, ops=ops, comparators=comparators):
            lhs = _evaluate(left, env)
            result: Any = True
            for op, comparator in zip(ops, comparators, strict=True):
                rhs = _evaluate(comparator, env)
                result = np.logical_and(result, _COMPARE[type(op)](lhs, rhs))
                lhs = rhs
            return result
        case ast.Call(func=ast.Name(id=name), args=args):
            return _FUNCTIONS[name][0](*(_evaluate(arg, env) for arg in args))
    raise AssertionError(f"unchecked node {ast.dump(node)}")  # pragma: no cover


def _uses_coordinates(tree: ast.AST) -> bool:
    """Whether the tree mentions ``x`` or ``y``."""
    return any(isinstance(n, ast.Name) and n.id in _VARIABLES for n in ast.walk(tree))


class Expression:
    """A checked expression of ``x`` and ``y``, callable on numpy arrays.

    Attributes:
        source: The expression text as written in the case file.
        key: The case key it came from (used in messages).
        tree: The checked syntax tree.
    """

    __slots__ = ("source", "key", "tree")

    source: str
    key: str
    tree: ast.Expression

    def __init__(self, source: str, key: str, tree: ast.Expression) -> None:
        object.__setattr__(self, "source", source)
        object.__setattr__(self, "key", key)
        object.__setattr__(self, "tree", tree)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("Expression is immutable")

    def __repr__(self) -> str:
        return f"Expression({self.source!r}, key={self.key!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Expression):
            return NotImplemented
        return self.source == other.source and self.key == other.key

    def __hash__(self) -> int:
        return hash((self.source, self.key))

    @property
    def is_constant(self) -> bool:
        """Whether the value does not depend on ``x`` or ``y``."""
        return not _uses_coordinates(self.tree)

    def constant_value(self) -> float:
        """Return the value of a constant expression.

        Raises:
            ValueError: If the expression depends on ``x`` or ``y``.
        """
        if not self.is_constant:
            raise ValueError(f"{self.key}: expression {self.source!r} is not constant")
        return float(self(np.zeros(1), np.zeros(1))[0])

    def __call__(self, x: Any, y: Any) -> np.ndarray:
        """Evaluate at points.

        Args:
            x: x coordinates (array-like).
            y: y coordinates, broadcastable against ``x``.

        Returns:
            A new float64 array with the broadcast shape of ``x`` and ``y``.
        """
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(y, dtype=np.float64)
        shape = np.broadcast_shapes(xa.shape, ya.shape)
        env: dict[str, Any] = {"x": xa, "y": ya, **_CONSTANTS}
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            value = _evaluate(self.tree.body, env)
        out = np.broadcast_to(np.asarray(value, dtype=np.float64), shape)
        return np.array(out, dtype=np.float64, copy=True)


def compile_expression(src: str, key: str) -> Expression:
    """Check an expression and make it callable.

    Args:
        src: The expression source, e.g. ``"where(x <= 20, x/3, 0)"``.
        key: The case key it comes from, e.g. ``"initial.depth"``; it starts every message.

    Returns:
        The checked expression.

    Raises:
        CaseError: If the source does not parse or uses anything outside the whitelist.
    """
    try:
        tree = check_expression(src)
    except ExpressionError as exc:
        raise CaseError(f"{key}: {exc}") from None
    return Expression(src, key, tree)
