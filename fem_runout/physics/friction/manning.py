"""Manning bed friction: the turbulent drag of open-channel hydraulics, no yield stress.

In place of seed eq. 2, the bed shear stress of Manning's formula (Gauckler–Manning–Strickler),
``τ_b = ρ g n² |v|²/h^{1/3}`` along ``-v``, so on the momentum ``q = h v`` of seed eq. 1::

    r(q) = -g n² |v| v / h^{1/3}                    (horizontal form)

``n`` [s/m^(1/3)] is Manning's roughness. This is the drag term of
:class:`~fem_runout.physics.friction.base.FrictionLaw` with the per-node coefficient
``k(h) = n²/h^{1/3}`` (Voellmy's constant ``1/ξ`` made depth-dependent) and no yield term
(``μ = 0``): a layer on any slope starts moving, and the implicit update, rate and slope
treatment are the shared ones.

**Slope-consistent form** (``bed`` given): the stress acts on the bed with the slope-normal
thickness ``h_n = h cosθ`` and the speed along the bed ``|U|``,
``τ_b = ρ g n² |U|²/h_n^{1/3}`` along ``-U``, i.e. ``k = n²/h_n^{1/3}`` with the drag gravity
``g_t = g s/cosθ`` of :meth:`~fem_runout.physics.friction.base.FrictionLaw.scales`, exactly as
Voellmy's turbulent term.

**Uniform flow** on a plane of angle θ (``S = tanθ``, :mod:`fem_runout.references.manning_sheet`):
with ``a = g S``, ``b = g n²/h^{4/3}`` (horizontal form) the sheet obeys ``du/dt = a - b u²``,
so ``u(t) = u_∞ tanh(t sqrt(a b))`` and the uniform-flow speed is Manning's formula
``u_∞ = h^{2/3} S^{1/2}/n``. In the slope form, along the bed
``dU/dt = g sinθ - g n² U²/h_n^{4/3}`` and ``U_∞ = h_n^{2/3} (sinθ)^{1/2}/n`` (the hydraulic
radius of a wide sheet is ``h_n``, the friction slope ``sinθ``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fem_runout.physics.friction.base import FrictionLaw
from fem_runout.physics.friction.registry import Parameter

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec
    from fem_runout.physics.slope import BedFrame

__all__ = ["ROUGHNESS", "Manning"]

#: Manning's roughness ``n``.
ROUGHNESS = Parameter("n", "Manning roughness", "s/m^(1/3)", gt=0.0, required=True)


class Manning(FrictionLaw):
    """Manning bed friction ``r = -g n² |v| v / h^{1/3}`` (module docstring), no yield stress.

    Case keys: ``n`` (required, > 0); ``mu``, ``phi_deg``, ``xi`` and ``gamma`` are refused.

    Args:
        n: Manning roughness [s/m^(1/3)] (> 0).
        gravity: ``g`` [m/s²].
        dry_tol: Dry depth [m].
    """

    name = "manning"
    parameters = (ROUGHNESS,)

    def __init__(self, n: float, gravity: float = 9.81, dry_tol: float = 1e-6) -> None:
        if not n > 0:
            raise ValueError(f"Manning needs n > 0, got {n!r}")
        super().__init__(0.0, gravity, dry_tol=dry_tol)
        self.n = float(n)

    def _shown(self) -> dict[str, float]:
        return {"n": self.n, "g": self.gravity}

    def drag_coefficient(self, h: np.ndarray, bed: BedFrame | None) -> np.ndarray:
        """``k = n²/h^{1/3}``, on a bed ``n²/h_n^{1/3}`` with ``h_n = h cosθ`` [s²/m]."""
        h_n = h if bed is None else h * bed.cos
        return self.n * self.n / np.cbrt(h_n)

    @classmethod
    def from_spec(cls, spec: FrictionSpec, gravity: float, dry_tol: float) -> Manning:
        """``Manning(n, g, dry_tol)``."""
        return cls(spec.n, gravity, dry_tol)
