"""Coulomb bed friction: seed eq. 2 without its turbulent term."""

from __future__ import annotations

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

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec
    from fem_runout.physics.slope import BedFrame

__all__ = ["Coulomb"]


class Coulomb(FrictionLaw):
    """Coulomb bed friction, seed eq. 2 without the turbulent term: ``r = -g μ h sgn|v| v/|v|``.

    Case keys: ``mu`` or ``phi_deg`` (exactly one), ``gamma`` (default :data:`GAMMA_DEFAULT`).
    A layer stays at rest where the slope is below ``μ`` (``has_yield``).

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
        super().__init__(mu, gravity, gamma, dry_tol)
        self.inv_xi = 0.0

    @property
    def xi(self) -> float:
        """Turbulence coefficient ``ξ``: infinite (no turbulent term)."""
        return float("inf")

    def drag_coefficient(self, h: np.ndarray, bed: BedFrame | None) -> float:
        """No drag: ``k = 0``."""
        return self.inv_xi

    @classmethod
    def check_parameters(cls, given: Mapping[str, Any]) -> None:
        """Exactly one of ``mu`` and ``phi_deg``."""
        check_one_coulomb_key(cls.name, given)

    @classmethod
    def from_spec(cls, spec: FrictionSpec, gravity: float, dry_tol: float) -> Coulomb:
        """``Coulomb(mu or tan(phi_deg), g, gamma, dry_tol)``."""
        return cls(coulomb_coefficient(spec.mu, spec.phi_deg), gravity, spec.gamma, dry_tol)
