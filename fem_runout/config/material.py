"""The ``material`` block of the case schema: density, basal friction and rheology.

The ``friction`` and ``rheology`` models are built from the laws' registries
(:data:`fem_runout.physics.friction.LAWS`, :data:`fem_runout.physics.rheology.RHEOLOGIES`):
a law registered there is a valid ``law`` value here, with its own parameters and checks.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field, create_model, model_validator

from fem_runout.config.types import Real, SpecError, StrictSpec
from fem_runout.physics.friction import LAWS
from fem_runout.physics.friction.base import coulomb_coefficient
from fem_runout.physics.friction.registry import ParameterError, Registry
from fem_runout.physics.rheology import RHEOLOGIES

__all__ = ["FrictionSpec", "MaterialSpec", "RheologySpec"]


class _LawSpec(StrictSpec):
    """A ``material`` block naming a registered law (``law``) and that law's parameters.

    The allowed ``law`` values and the other keys come from a registry
    (:class:`fem_runout.physics.friction.registry.Registry`): each key is one law's
    :class:`~fem_runout.physics.friction.registry.Parameter`, with its bounds. ``law: none``
    takes no other key; another law takes its own keys only, needs its required ones, gets its
    defaults filled in and runs its own checks (messages name the key).
    """

    registry: ClassVar[Registry]
    law: str = "none"  # replaced by the Literal of the registered names (:func:`_law_spec`)

    @model_validator(mode="before")
    @classmethod
    def _fill_defaults(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("law") in cls.registry:
            return cls.registry.with_defaults(data["law"], data)
        return data

    @model_validator(mode="after")
    def _check_law(self) -> _LawSpec:
        given = {p.name: getattr(self, p.name) for p in self.registry.parameters()
                 if getattr(self, p.name) is not None}
        if self.law == "none":
            if given:
                raise SpecError("not allowed with law 'none'", next(iter(given)))
            return self
        try:
            self.registry.check(self.law, given)
        except ParameterError as exc:
            raise SpecError(str(exc), exc.key) from None
        return self


def _law_spec(name: str, base: type[_LawSpec], registry: Registry, doc: str) -> Any:
    """Build the block model ``name``: ``law`` plus every registered law's parameters."""
    fields: dict[str, Any] = {"law": (Literal[("none", *registry.names())], "none")}
    for p in registry.parameters():
        fields[p.name] = (Real | None, Field(None, description=p.describe(), **p.bounds()))
    model = create_model(name, __base__=base, __module__=__name__, __doc__=doc, **fields)
    model.registry = registry
    return model


class _FrictionBase(_LawSpec):
    """``material.friction``: the fields come from :data:`LAWS` (:func:`_law_spec`)."""

    mu: Real | None = None  # replaced with its bounds by _law_spec
    phi_deg: Real | None = None  # replaced with its bounds by _law_spec

    @property
    def mu_value(self) -> float | None:
        """The friction coefficient: ``mu``, or ``tan(phi_deg)``, or ``None`` if neither."""
        if self.mu is None and self.phi_deg is None:
            return None
        return coulomb_coefficient(self.mu, self.phi_deg)


FrictionSpec = _law_spec("FrictionSpec", _FrictionBase, LAWS, """Basal friction (seed eq. 2).

    ``law`` is ``none`` or a law of :data:`fem_runout.physics.friction.LAWS` (``coulomb``,
    ``voellmy``, ``manning``); the other keys are the laws' parameters (``mu``, ``phi_deg``,
    ``xi``, ``n``, ``gamma``: docs/case_schema.md), each accepted only by the laws that take
    it. ``gamma`` (coulomb, voellmy) defaults to the value in
    :mod:`fem_runout.physics.friction.base`.
    """)

RheologySpec = _law_spec("RheologySpec", _LawSpec, RHEOLOGIES, """Internal rheology.

    ``law`` is ``none`` or a rheology of :data:`fem_runout.physics.rheology.RHEOLOGIES`
    (``bingham``: ``viscosity`` [Pa s] and ``yield_stress`` [Pa], both required).
    """)


class MaterialSpec(StrictSpec):
    """Material density [kg/m^3], friction and rheology."""

    density: Real = Field(1000.0, gt=0)
    friction: FrictionSpec = FrictionSpec()
    rheology: RheologySpec = RheologySpec()
