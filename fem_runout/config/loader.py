"""Read a case (YAML file or mapping), apply overrides, validate, report errors clearly.

Every problem becomes one :class:`~fem_runout.errors.CaseError` whose message reads
``<file>: <key.path>: <what is wrong>; allowed: <what is allowed>``.
"""

from __future__ import annotations

import re
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import annotated_types as at
import yaml
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from fem_runout.config.schema import Case, SpecError
from fem_runout.errors import CaseError

__all__ = ["dump_resolved", "load_case", "parse_override", "read_yaml"]

_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")


class _CaseLoader(yaml.SafeLoader):
    """Safe YAML loader that rejects duplicate keys and reads ``1e-6`` as a float."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        """Build a mapping, rejecting a key that appears twice."""
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


_CaseLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789"))


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """Describe a YAML error with its (1-based) line and column."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    if mark is None:
        return f"invalid YAML: {problem}"
    return f"invalid YAML at line {mark.line + 1}, column {mark.column + 1}: {problem}"


def read_yaml(text: str, label: str) -> Any:
    """Parse YAML text with the case loader.

    Args:
        text: The YAML text.
        label: Name used in messages (a file name or ``override 'k=v'``).

    Raises:
        CaseError: If the text is not valid YAML.
    """
    try:
        return yaml.load(text, Loader=_CaseLoader)
    except yaml.YAMLError as exc:
        raise CaseError(f"{label}: {_yaml_problem(exc)}") from None


def _plain(value: Any) -> Any:
    """Deep copy of mappings/sequences as plain dicts/lists."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _read_source(source: str | Path | Mapping[str, Any]) -> tuple[Any, str, Path | None]:
    """Return the raw case data, the label used in messages and the case file folder."""
    if isinstance(source, Mapping):
        return _plain(source), "case", None
    path = Path(source)
    label = str(source)
    if not path.exists():
        raise CaseError(f"case file '{label}' does not exist")
    if not path.is_file():
        raise CaseError(f"case file '{label}' is not a file")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseError(f"case file '{label}' cannot be read: {exc}") from None
    return read_yaml(text, label), label, path.resolve().parent


def parse_override(text: str) -> tuple[str, Any]:
    """Split ``"key.path=value"``; the value is parsed as YAML (``2`` -> int, ``[1, 2]`` -> list).

    Raises:
        CaseError: If there is no ``=``, the key is not a dotted path or the value is bad YAML.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not _KEY.match(key):
        raise CaseError(f"override '{text}' must look like key.path=value (for example time.end=2)")
    return key, read_yaml(value, f"override '{text}'")


def _normalise_overrides(
    overrides: Mapping[str, Any] | Sequence[str | tuple[str, Any]] | None,
) -> list[tuple[str, Any, str]]:
    """Turn overrides into ``(key, value, how to name it in messages)`` triples."""
    if overrides is None:
        return []
    if isinstance(overrides, str):
        overrides = [overrides]
    pairs = overrides.items() if isinstance(overrides, Mapping) else overrides
    items = []
    for item in pairs:
        if isinstance(item, str):
            items.append((*parse_override(item), f"override '{item}'"))
            continue
        key, value = item
        if not isinstance(key, str) or not _KEY.match(key):
            raise CaseError(f"override key {key!r} must be a dotted path like time.end")
        items.append((key, _plain(value), f"override '{key}={value}'"))
    return items


def _apply_override(raw: dict[str, Any], key: str, value: Any, label: str) -> None:
    """Set ``raw[a][b][c] = value`` for ``key = "a.b.c"``, creating mappings on the way."""
    parts = key.split(".")
    node = raw
    for i, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, dict):
            where = ".".join(parts[: i + 1])
            raise CaseError(f"{label}: '{where}' is {child!r}, not a mapping")
        node = child
    node[parts[-1]] = value


# --- turning pydantic errors into one message ---------------------------------------------


def _model_of(annotation: Any) -> type[BaseModel] | None:
    """Return the pydantic model inside ``annotation`` (possibly ``Model | None``), if any."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        for arg in typing.get_args(annotation):
            model = _model_of(arg)
            if model is not None:
                return model
    return None


def _model_at(loc: Sequence[Any]) -> type[BaseModel] | None:
    """Return the model that validates the mapping at ``loc`` (``()`` is the case itself)."""
    model: type[BaseModel] | None = Case
    for part in loc:
        if model is None or part not in model.model_fields:
            return None
        model = _model_of(model.model_fields[part].annotation)
    return model


def _field_at(loc: Sequence[Any]) -> FieldInfo | None:
    if not loc:
        return None
    model = _model_at(loc[:-1])
    return None if model is None else model.model_fields.get(loc[-1])


def _keys(model: type[BaseModel]) -> str:
    return ", ".join(model.model_fields)


def _constraints(field: FieldInfo | None) -> str | None:
    """``"> 0 and <= 1"`` for a field with numeric bounds."""
    if field is None:
        return None
    symbols = {at.Gt: ("gt", ">"), at.Ge: ("ge", ">="), at.Lt: ("lt", "<"), at.Le: ("le", "<=")}
    parts = []
    for item in field.metadata:
        if type(item) in symbols:
            attr, symbol = symbols[type(item)]
            parts.append(f"{symbol} {getattr(item, attr):g}")
    return " and ".join(parts) or None


def _literal_values(field: FieldInfo | None) -> list[str]:
    if field is None:
        return []
    annotation = field.annotation
    if typing.get_origin(annotation) is Literal:
        return [str(v) for v in typing.get_args(annotation)]
    return []


def _describe_error(error: Mapping[str, Any]) -> tuple[tuple[Any, ...], str]:
    """Return the key path and the explanation for one pydantic error."""
    loc = tuple(error["loc"])
    kind = error["type"]
    value = error.get("input")
    if kind == "value_error":
        exc = error.get("ctx", {}).get("error")
        if isinstance(exc, SpecError) and exc.key:
            loc = (*loc, exc.key)
        return loc, str(exc) if exc is not None else error["msg"]
    if kind == "extra_forbidden":
        model = _model_at(loc[:-1])
        allowed = f"; allowed keys: {_keys(model)}" if model else ""
        return loc, f"unknown key{allowed}"
    if kind == "missing":
        model = _model_at(loc)
        keys = f" (a mapping with keys {_keys(model)})" if model else ""
        return loc, f"required key is missing{keys}"
    if kind == "literal_error":
        noun = loc[-1] if loc and loc[-1] in ("law", "method") else "value"
        allowed = ", ".join(_literal_values(_field_at(loc))) or error["ctx"]["expected"]
        return loc, f"{value!r} is not a known {noun}; allowed: {allowed}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        bounds = _constraints(_field_at(loc)) or error["msg"].removeprefix("Input should be ")
        shown = f"{value:g}" if isinstance(value, int | float) else repr(value)
        return loc, f"must be {bounds}, got {shown}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        model = _model_at(loc)
        keys = f" with keys {_keys(model)}" if model else ""
        return loc, f"must be a mapping{keys}, got {value!r}"
    if kind == "string_type":
        return loc, f"must be a string, got {value!r}"
    return loc, f"{error['msg']}, got {value!r}"


def _format_loc(loc: Sequence[Any]) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _message(exc: ValidationError, label: str, overrides: list[tuple[str, Any, str]]) -> str:
    """One line naming the file, the key path and the first problem."""
    errors = exc.errors()
    loc, text = _describe_error(errors[0])
    key = _format_loc(loc)
    for override_key, _, how in overrides:
        if (
            key == override_key
            or key.startswith(override_key + ".")
            or (override_key.startswith(key + ".") and key)
        ):
            text += f" (set by {how})"
            break
    if len(errors) > 1:
        more = len(errors) - 1
        text += f" (and {more} more problem{'s' if more > 1 else ''})"
    return f"{label}: {key}: {text}" if key else f"{label}: {text}"


def load_case(
    source: str | Path | Mapping[str, Any],
    overrides: Mapping[str, Any] | Sequence[str | tuple[str, Any]] | None = None,
) -> Case:
    """Read, override and validate a case.

    Args:
        source: Path of a YAML case file, or the case as a mapping.
        overrides: ``"key.path=value"`` strings (values parsed as YAML), ``(key, value)``
            pairs, or a mapping of dotted keys to values; applied in order before validation.

    Returns:
        The validated case; ``case.source_dir`` is the case file folder (``None`` for a
        mapping). With ``terrain.dem`` the domain extent, cell size and CRS are filled from
        the DEM (see :func:`fem_runout.terrain.resolve.resolve_terrain`); an outline or a
        mesh file is read and checked (:func:`fem_runout.meshing.resolve.resolve_domain`).

    Raises:
        CaseError: For a missing or unreadable file, invalid YAML, a bad override, an unknown
            key or a bad value; the message names the file and the key path.
    """
    raw, label, source_dir = _read_source(source)
    if not isinstance(raw, dict):
        got = "an empty file" if raw is None else f"{type(raw).__name__} {raw!r}"
        raise CaseError(
            f"{label}: the top level must be a mapping with keys {_keys(Case)}; got {got}"
        )
    items = _normalise_overrides(overrides)
    for key, value, how in items:
        _apply_override(raw, key, value, how)
    try:
        case = Case.model_validate(raw)
    except ValidationError as exc:
        raise CaseError(_message(exc, label, items)) from None
    if source_dir is not None:
        case = case.with_source_dir(source_dir)
    if (case.terrain.dem is not None or case.initial.release is not None
            or case.domain.kind != "rectangle"):
        from fem_runout.terrain.resolve import resolve_terrain

        try:
            case = resolve_terrain(case)
        except CaseError as exc:
            raise CaseError(f"{label}: {exc}") from None
    return case


def dump_resolved(case: Case) -> str:
    """Return the case as YAML with every default filled in.

    ``load_case`` reads the text back (after ``yaml.safe_load``) to an equal case.
    """
    data = case.model_dump(mode="json", exclude_none=True)
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
