"""Registries of material laws: the one place that names them and lists their parameters.

A law is a class with a ``name`` (its key in case files, ``law: <name>``), a tuple of
:class:`Parameter` (the other keys of its block, with bounds, units and defaults) and a
``from_spec`` class method that builds it from the validated block. The case schema
(:mod:`fem_runout.config.schema`) reads the registry to build the ``material.friction`` and
``material.rheology`` blocks: adding a law is one class and one :meth:`Registry.register` call,
with no schema edit (docs/extending.md).

This module imports nothing of the configuration, so that the schema can import it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Parameter", "ParameterError", "Registry"]


class ParameterError(ValueError):
    """A law's parameters do not fit together; ``key`` (if set) is the key at fault.

    The schema turns it into a :class:`fem_runout.config.types.SpecError` (same message, same
    key), which the loader reports with the key path.
    """

    def __init__(self, message: str, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class Parameter:
    """One key of a law's block in the case file.

    Attributes:
        name: The key (``material.friction.<name>``).
        meaning: What it is, in a few words (messages and docs).
        units: Its units (``""`` for none).
        gt, ge, lt: Bounds (strict lower, lower, strict upper), or None.
        default: Value filled in when the law uses the key and the case leaves it out
            (None: no default).
        required: The law needs the key (and it has no default).
    """

    name: str
    meaning: str
    units: str = ""
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    default: float | None = None
    required: bool = False

    def bounds(self) -> dict[str, float]:
        """Return the bounds as keyword arguments of :func:`pydantic.Field`."""
        return {k: v for k, v in (("gt", self.gt), ("ge", self.ge), ("lt", self.lt))
                if v is not None}

    def describe(self) -> str:
        """Return ``"meaning, units"`` (for messages)."""
        return f"{self.meaning}, {self.units}" if self.units else self.meaning


class Registry:
    """Named law classes in registration order, and the union of their parameters.

    Args:
        kind: What the laws are, for messages (``"friction law"``).
    """

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._laws: dict[str, type] = {}

    def register(self, law: type) -> type:
        """Add ``law`` and return it (so this can also decorate the class).

        Its ``name`` must be new, and a parameter it shares with another law must be declared
        the same way (one key, one meaning and one set of bounds).
        """
        name = getattr(law, "name", "")
        if not name or name == "none" or name in self._laws:
            raise ValueError(f"{self.kind} name {name!r} is empty, reserved or already taken")
        known = {p.name: p for p in self.parameters()}
        for p in law.parameters:
            if p.name == "law" or (p.name in known and known[p.name] != p):
                raise ValueError(f"{self.kind} '{name}': parameter '{p.name}' clashes with "
                                 "another law's parameter of the same name")
        self._laws[name] = law
        return law

    def names(self) -> tuple[str, ...]:
        """Return the registered names, in registration order."""
        return tuple(self._laws)

    def get(self, name: str) -> Any:
        """Return the law class called ``name``; KeyError listing the registered names otherwise."""
        try:
            return self._laws[name]
        except KeyError:
            raise KeyError(f"unknown {self.kind} '{name}'; available: "
                           f"{', '.join(self._laws)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self._laws

    def __iter__(self) -> Iterator[type]:
        return iter(self._laws.values())

    def parameters(self) -> tuple[Parameter, ...]:
        """Return every law's parameters, each name once.

        Physical ones first, those with a default (numerical settings) last, otherwise in
        registration order.
        """
        seen: dict[str, Parameter] = {}
        for law in self._laws.values():
            for p in law.parameters:
                seen.setdefault(p.name, p)
        values = list(seen.values())
        return tuple([p for p in values if p.default is None]
                     + [p for p in values if p.default is not None])

    def users(self, key: str) -> tuple[str, ...]:
        """Return the names of the laws that take the parameter ``key``."""
        return tuple(n for n, law in self._laws.items()
                     if any(p.name == key for p in law.parameters))

    def check(self, name: str, given: Mapping[str, Any]) -> None:
        """Check the keys ``given`` (the non-None parameters) for the law ``name``.

        Raises:
            ParameterError: A key the law does not take, a required key missing, or the
                law's own check (:meth:`check_parameters` of the class) failing.
        """
        law = self.get(name)
        own = {p.name: p for p in law.parameters}
        for key in given:
            if key not in own:
                used = ", ".join(f"'{u}'" for u in self.users(key))
                raise ParameterError(f"not used by law '{name}' (only by {used}); law "
                                     f"'{name}' takes: {', '.join(own) or 'nothing'}", key)
        for p in own.values():
            if p.required and given.get(p.name) is None:
                raise ParameterError(f"required for law '{name}' ({p.describe()})", p.name)
        law.check_parameters(given)

    def with_defaults(self, name: str, data: Mapping[str, Any]) -> dict[str, Any]:
        """Return ``data`` with the defaults of the law ``name`` filled in for missing keys."""
        filled = dict(data)
        for p in self.get(name).parameters:
            if p.default is not None and filled.get(p.name) is None:
                filled[p.name] = p.default
        return filled
