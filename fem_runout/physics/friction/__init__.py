"""Bed friction laws (seed eq. 2 and its relatives) and their registry.

Every law has the form ``r(q) = -(g_c μ h sgn|v| + g_t k(h) |v|²) v/|v|`` on the momentum:
a yield (Coulomb) term and a drag term with a per-node coefficient ``k``. A law states its
parameters, ``μ`` and ``k`` (:class:`FrictionLaw`); the explicit rate, the exact held-layer
test and the per-node Newton update of seed §3.1.1 are shared (:mod:`.base`).

Registered laws (``material.friction.law``), in this order:

* ``coulomb`` (:class:`Coulomb`): ``k = 0``;
* ``voellmy`` (:class:`Voellmy`, seed eq. 2): ``k = 1/ξ``;
* ``manning`` (:class:`Manning`): ``μ = 0``, ``k = n²/h^{1/3}``.

Adding a law is one module and one :func:`register_law` line below (docs/extending.md); the
case schema reads :data:`LAWS` for the allowed names and keys.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from fem_runout.physics.friction.base import FrictionLaw, relaxed_sign
from fem_runout.physics.friction.coulomb import Coulomb
from fem_runout.physics.friction.manning import Manning
from fem_runout.physics.friction.registry import Parameter, ParameterError, Registry
from fem_runout.physics.friction.voellmy import Voellmy

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec

__all__ = [
    "LAWS",
    "Coulomb",
    "FrictionLaw",
    "Manning",
    "Parameter",
    "ParameterError",
    "Voellmy",
    "friction_from_spec",
    "register_law",
    "relaxed_sign",
]

#: The friction laws, by name, in registration order.
LAWS = Registry("friction law")
#: Add a :class:`FrictionLaw` subclass to :data:`LAWS` (its ``name`` must be new).
register_law = LAWS.register

register_law(Coulomb)
register_law(Voellmy)
register_law(Manning)


def friction_from_spec(
    spec: FrictionSpec, gravity: float, dry_tol: float = 1e-6
) -> FrictionLaw | None:
    """Build the friction law of a case: ``None`` for ``law: none``.

    Args:
        spec: The validated friction block of the case.
        gravity: ``g`` [m/s²].
        dry_tol: Dry depth [m] (the case's ``numerics.dry_tolerance``).
    """
    if spec.law == "none":
        return None
    return LAWS.get(spec.law).from_spec(spec, gravity, dry_tol)
