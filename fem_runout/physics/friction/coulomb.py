"""Coulomb bed friction: seed eq. 2 without its turbulent term (Voellmy with ξ = ∞)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from fem_runout.physics.friction.base import (
    GAMMA,
    GAMMA_DEFAULT,
    MU,
    PHI_DEG,
    FrictionLaw,
    coulomb_coefficient,
)
from fem_runout.physics.friction.voellmy import Voellmy

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec

__all__ = ["Coulomb"]


class Coulomb(Voellmy):
    """Coulomb bed friction, seed eq. 2 without the turbulent term: ``r = -g μ h sgn|v| v/|v|``.

    The seed's special case of Voellmy with ``ξ = ∞`` (``inv_xi = 1/∞ = 0``: no drag). Case
    keys: ``mu`` or ``phi_deg`` (exactly one), ``gamma`` (default :data:`GAMMA_DEFAULT`). A
    layer stays at rest where the slope is below ``μ`` (``has_yield``).

    Args:
        mu: Friction coefficient ``tanφ`` [-].
        gravity: ``g`` [m/s²].
        gamma: Sign relaxation of seed eq. 20 [m/s] (explicit :meth:`rate` only).
        dry_tol: Dry depth [m].

    Attributes:
        inv_xi: 0: no turbulent term (``xi`` is infinite).
    """

    name = "coulomb"
    parameters = (MU, PHI_DEG, GAMMA)

    def __init__(self, mu: float, gravity: float = 9.81, gamma: float = GAMMA_DEFAULT,
                 dry_tol: float = 1e-6) -> None:
        super().__init__(mu, math.inf, gravity, gamma, dry_tol)

    def _shown(self) -> dict[str, float]:
        return FrictionLaw._shown(self)

    @classmethod
    def from_spec(cls, spec: FrictionSpec, gravity: float, dry_tol: float) -> Coulomb:
        """``Coulomb(mu or tan(phi_deg), g, gamma, dry_tol)``."""
        return cls(coulomb_coefficient(spec.mu, spec.phi_deg), gravity, spec.gamma, dry_tol)
