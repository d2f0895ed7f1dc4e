import numpy as np
import pytest

from fem_runout.config.expr import Expression, compile_expression
from fem_runout.errors import CaseError

X = np.linspace(-3.0, 40.0, 11)
Y = np.linspace(0.5, 7.0, 11)


@pytest.mark.parametrize(
    ("src", "expected"),
    [
        ("100 - x/3", 100 - X / 3),
        ("where(x <= 20, x/3, 0)", np.where(X <= 20, X / 3, 0.0)),
        (
            "sqrt(maximum(25 - (x-25)**2 - (y-25)**2, 0))",
            np.sqrt(np.maximum(25 - (X - 25) ** 2 - (Y - 25) ** 2, 0)),
        ),
        (
            "15*exp(-((x-3.5)**2+(y-3.5)**2)) + 4*exp(-((x-7)**2+(y-7)**2))",
            15 * np.exp(-((X - 3.5) ** 2 + (Y - 3.5) ** 2))
            + 4 * np.exp(-((X - 7) ** 2 + (Y - 7) ** 2)),
        ),
        (
            "hypot(x, y) + abs(-x) % 3 - minimum(x, y)",
            np.hypot(X, Y) + np.abs(-X) % 3 - np.minimum(X, Y),
        ),
        (
            "sin(pi*x) * cos(y) + tan(0.1) + log(e)",
            np.sin(np.pi * X) * np.cos(Y) + np.tan(0.1) + 1.0,
        ),
        ("-x ** 2 + +y", -(X**2) + Y),
        ("(0 < x < 10) * 1.5", np.where((X > 0) & (X < 10), 1.5, 0.0)),
        ("(x > 1 and y < 5) or not x != 40", ((X > 1) & (Y < 5)) | (X == 40)),
        ("2 ** -1 + 7 % 4", np.full_like(X, 3.5)),
        (
            "clip(x, 0, 10) + floor(y) + ceil(y) + tanh(y) + arctan2(y, x)",
            np.clip(X, 0, 10) + np.floor(Y) + np.ceil(Y) + np.tanh(Y) + np.arctan2(Y, X),
        ),
    ],
)
def test_values_match_numpy(src: str, expected: np.ndarray) -> None:
    value = compile_expression(src, "k")(X, Y)
    assert value.dtype == np.float64
    assert value.shape == X.shape
    np.testing.assert_allclose(value, expected, rtol=1e-14, atol=1e-14)


def test_constant_broadcasts_to_shape_of_x() -> None:
    expr = compile_expression("10", "initial.free_surface")
    x = np.zeros((4, 3))
    value = expr(x, x)
    assert value.shape == (4, 3)
    assert value.dtype == np.float64
    assert np.all(value == 10.0)
    value[0, 0] = -1.0  # a writable copy
    assert expr(x, x)[0, 0] == 10.0
    assert expr.is_constant
    assert expr.constant_value() == 10.0


def test_scalar_y_broadcasts() -> None:
    expr = compile_expression("x + y", "k")
    np.testing.assert_array_equal(expr(np.arange(3.0), 1.0), [1.0, 2.0, 3.0])


def test_constant_helpers() -> None:
    expr = compile_expression("x/3", "terrain.elevation")
    assert isinstance(expr, Expression)
    assert not expr.is_constant
    with pytest.raises(ValueError):
        expr.constant_value()
    assert compile_expression("2*pi", "k").constant_value() == pytest.approx(2 * np.pi)
    assert expr.source == "x/3"
    with pytest.raises(AttributeError):
        expr.source = "y"  # type: ignore[misc]


def test_division_by_zero_gives_inf_without_warning() -> None:
    with np.errstate(all="raise"):
        value = compile_expression("where(x > 0, 1/x, 0)", "k")(np.array([0.0, 2.0]), 0.0)
    np.testing.assert_array_equal(value, [0.0, 0.5])


@pytest.mark.parametrize(
    ("src", "what"),
    [
        ("__import__('os')", "call of '__import__'"),
        ("x.__class__", "attribute access"),
        ("(lambda: 1)()", "lambda"),
        ("[i for i in range(3)]", "comprehension"),
        ("{1:2}", "dict"),
        ('"abc"', "constant 'abc'"),
        ("open('f')", "call of 'open'"),
        ("x[0]", "subscript"),
        ("foo", "unknown name 'foo'"),
        ("sqrt(x, y=1)", "keyword argument"),
        ("1 +", "cannot parse"),
        ("True", "boolean"),
        ("f'{x}'", "f-string"),
        ("(z := 1)", "assignment"),
        ("sqrt(*x)", "starred"),
        ("sqrt(x, y)", "takes 1 argument"),
        ("x if y else 0", "conditional"),
        ("x @ y", "operator"),
        ("x is y", "comparison operator"),
        ("np.sqrt(x)", "attribute access"),
        ("", "empty"),
    ],
)
def test_rejected(src: str, what: str) -> None:
    with pytest.raises(CaseError) as info:
        compile_expression(src, "initial.depth")
    message = str(info.value)
    assert message.startswith("initial.depth: ")
    assert what in message
    if what != "cannot parse" and what != "empty":
        assert "is not allowed" in message
        assert "allowed functions: abs," in message
        assert "names: x, y, pi, e" in message


def test_rejection_message_example() -> None:
    with pytest.raises(
        CaseError,
        match=r"^initial\.depth: expression \"__import__\('os'\)\" "
        r"is not allowed: call of '__import__' \(allowed functions: abs, ",
    ):
        compile_expression("__import__('os')", "initial.depth")
