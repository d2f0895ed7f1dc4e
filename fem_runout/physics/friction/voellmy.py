"""Voellmy bed friction, seed eq. 2: Coulomb plus a turbulent drag ``g |v|²/ξ``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.physics.friction.base import (
    GAMMA,
    GAMMA_DEFAULT,
    MU,
    PHI_DEG,
    FrictionLaw,
    check_one_coulomb_key,
    coulomb_coefficient,
)
from fem_runout.physics.friction.registry import Parameter

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec
    from fem_runout.physics.slope import BedFrame

__all__ = ["XI", "Voellmy"]

#: Turbulence coefficient ``ξ`` of seed eq. 2.
XI = Parameter("xi", "turbulence coefficient", "m/s^2", gt=0.0, required=True)


class Voellmy(FrictionLaw):
    """Voellmy bed friction, seed eq. 2: ``r = -(g μ h sgn|v| + g |v|²/ξ) v/|v|``.

    The drag coefficient is the constant ``k = 1/ξ``; on a bed the sheet's terminal speed along
    it is ``|U| = sqrt(ξ h_n (sinθ - μ cosθ))`` (:mod:`fem_runout.references.slope`). Case keys:
    ``mu`` or ``phi_deg`` (exactly one), ``xi`` (required), ``gamma`` (default
    :data:`GAMMA_DEFAULT`).

    Args:
        mu: Friction coefficient ``tanφ`` [-].
        xi: Turbulence coefficient ``ξ`` [m/s²] (> 0).
        gravity: ``g`` [m/s²].
        gamma: Sign relaxation of seed eq. 20 [m/s] (explicit :meth:`rate` only).
        dry_tol: Dry depth [m].

    Attributes:
        inv_xi: ``1/ξ`` [s²/m], the drag coefficient.
    """

    name = "voellmy"
    parameters = (MU, PHI_DEG, XI, GAMMA)

    def __init__(self, mu: float, xi: float, gravity: float = 9.81,
                 gamma: float = GAMMA_DEFAULT, dry_tol: float = 1e-6) -> None:
        if not xi > 0:
            raise ValueError(f"Voellmy needs xi > 0, got {xi!r}")
        super().__init__(mu, gravity, gamma, dry_tol)
        self.inv_xi = 1.0 / xi

    @property
    def xi(self) -> float:
        """Turbulence coefficient ``ξ`` [m/s²]."""
        return math.inf if self.inv_xi == 0.0 else 1.0 / self.inv_xi

    def _shown(self) -> dict[str, float]:
        return {"mu": self.mu, "xi": self.xi, "g": self.gravity, "gamma": self.gamma}

    def drag_coefficient(self, h: np.ndarray, bed: BedFrame | None) -> float:
        """``k = 1/ξ`` (the same on every node)."""
        return self.inv_xi

    @classmethod
    def check_parameters(cls, given: Mapping[str, Any]) -> None:
        """Exactly one of ``mu`` and ``phi_deg``."""
        check_one_coulomb_key(cls.name, given)

    @classmethod
    def from_spec(cls, spec: FrictionSpec, gravity: float, dry_tol: float) -> Voellmy:
        """``Voellmy(mu or tan(phi_deg), xi, g, gamma, dry_tol)``."""
        return cls(coulomb_coefficient(spec.mu, spec.phi_deg), spec.xi, gravity, spec.gamma,
                   dry_tol)
