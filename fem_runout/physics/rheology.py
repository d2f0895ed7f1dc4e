"""Depth-integrated Bingham rheology, seed eqs. 3-7.

The deviatoric stress ``σ`` enters the momentum equations (seed eq. 1) as ``(1/ρ) ∇·(h σ)``
(the diffusive flux ``G`` of seed eq. 8). It is built from

* the in-plane strain rate ``D = ½(∇v + ∇vᵀ)`` (seed eq. 4; its printed lower-left entry
  ``½(∂x u + ∂y v)`` is a typo for ``½(∂y u + ∂x v)``: ``D`` is symmetric),
* the depth-averaged tensor ``D̄`` (seed eq. 5): ``D`` bordered by ``½ ∂z v`` and
  ``D̄_33 = -(D_11 + D_22)``, with the second invariant ``I₂ = ½ D̄ : D̄``,
* the vertical shear ``∂z v = 3/(2+ψ) v/h`` (seed eq. 6) with ``ψ = τ_Y/τ_B ∈ [0, 1]`` the root
  of ``48ψ² - (114 + 32a)ψ + 65 = 0``, ``a = 6 μ |v| / (τ_Y h)`` (seed eq. 7),
* the Bingham law (seed eq. 3) ``σ = (2μ + τ_Y / sqrt(I₂ + δ²)) D = 2 μ_eff D``.

Choices, stated:

* Seed eq. 3 as printed divides ``τ_Y`` by ``I₂``, which is not a stress (``I₂`` is in 1/s²).
  The usual Bingham law divides by ``sqrt(I₂)``: for simple shear ``u = γ̇ y`` it gives
  ``σ_xy = μ γ̇ + τ_Y``. That is what is implemented.
* ``δ`` (``reg``, default 1e-3 1/s) regularises the yield term (bi-viscous / Papanastasiou-type
  regularisation): ``μ_eff = μ + τ_Y / (2 sqrt(I₂ + δ²))`` stays finite, at most
  ``μ + τ_Y/(2δ)``, at zero strain rate.
* Convention: ``σ = 2 μ_eff D``, so a Newtonian fluid (``τ_Y = 0``) has ``μ_eff = μ`` and
  ``σ_xy = μ ∂y u`` in simple shear ``u = u(y)``.
* Of the two roots of seed eq. 7 (product 65/48 > 1), only the smaller lies in ``[0, 1]``: it
  goes from 0.951 (``a = 0``, a plug) to 0 (``a → ∞``, or ``τ_Y = 0``). It is computed in the
  cancellation-free form ``ψ = 130 τ_Y h / (B + sqrt(B² - 12480 (τ_Y h)²))``,
  ``B = 114 τ_Y h + 192 μ |v|``, and clipped to ``[0, 1]``.

In this model the Bingham stress acts on in-plane velocity gradients only (it is a diffusion of
momentum); the resistance of the bed comes from the friction law (:mod:`.friction`). The
vertical shear ``∂z v`` only raises ``I₂`` and so lowers the yield part of ``μ_eff``.

Registry
--------
The rheologies (``material.rheology.law``) are the :class:`Rheology` subclasses registered in
:data:`RHEOLOGIES` (today ``bingham``); the case schema reads it for the allowed names and
keys, as for the friction laws (:mod:`fem_runout.physics.friction.registry`,
docs/extending.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from fem_runout.physics.friction.registry import Parameter, Registry

if TYPE_CHECKING:
    from fem_runout.config.schema import RheologySpec

__all__ = [
    "RHEOLOGIES",
    "Bingham",
    "Rheology",
    "plug_ratio",
    "register_rheology",
    "rheology_from_spec",
    "strain_rate",
]

Array = np.ndarray

#: Regularisation strain rate ``δ`` [1/s] of a yield term (written here only).
REG_DEFAULT = 1e-3


def strain_rate(grad_u: Array) -> Array:
    """In-plane strain rate ``D = ½(∇v + ∇vᵀ)`` of seed eq. 4.

    Args:
        grad_u: (n, 2, 2) velocity gradient, ``grad_u[:, i, j] = ∂_j v_i``
            (``[[∂x u, ∂y u], [∂x v, ∂y v]]``).

    Returns:
        (n, 2, 2) symmetric ``D``.
    """
    grad_u = np.asarray(grad_u, dtype=float)
    return 0.5 * (grad_u + np.swapaxes(grad_u, 1, 2))


def plug_ratio(speed: Array, h: Array, viscosity: float, yield_stress: float) -> Array:
    """``ψ = τ_Y/τ_B``: the root in ``[0, 1]`` of seed eq. 7, ``48ψ² - (114+32a)ψ + 65 = 0``.

    ``a = 6 μ |v| / (τ_Y h)``. Computed as ``130 τ_Y h / (B + sqrt(B² - 12480 (τ_Y h)²))``
    with ``B = 114 τ_Y h + 192 μ |v|`` (the smaller root, no cancellation); ``ψ = 0`` when
    ``τ_Y = 0`` (Newtonian) and ``ψ = 65/(57 + sqrt(3249 - 3120)) ≈ 0.951`` when ``v = 0``.

    Args:
        speed: ``|v|`` [m/s], shape (n,).
        h: Depth [m], shape (n,), > 0.
        viscosity: ``μ`` [Pa s].
        yield_stress: ``τ_Y`` [Pa].
    """
    th = yield_stress * np.asarray(h, dtype=float)
    big_b = 114.0 * th + 192.0 * viscosity * np.asarray(speed, dtype=float)
    disc = np.sqrt(np.maximum(big_b * big_b - 12480.0 * th * th, 0.0))
    den = big_b + disc
    psi = np.divide(130.0 * th, den, out=np.zeros_like(den), where=den > 0)
    return np.clip(psi, 0.0, 1.0)


class Rheology:
    """An internal rheology: ``σ = 2 μ_eff D`` with an effective viscosity per node.

    What the solvers use: :meth:`effective_viscosity` (TG2-PC per cell, DAMPM per particle),
    ``density`` (``ν = μ_eff/ρ``) and ``viscosity``, the part of ``μ_eff`` that multiplies the
    strain rate without bound (it limits DAMPM's explicit step; a yield part has a bounded
    stress). A subclass sets ``name`` and ``parameters`` (its keys in ``material.rheology``)
    and implements :meth:`effective_viscosity` and :meth:`from_spec`.

    Attributes:
        name: Key in case files (``material.rheology.law``).
        parameters: The rheology's other keys.
        viscosity: Newtonian part of the viscosity [Pa s].
        density: ``ρ`` [kg/m³].
    """

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    viscosity: float
    density: float

    @classmethod
    def check_parameters(cls, given: Mapping[str, Any]) -> None:
        """Check the keys ``given`` against each other (beyond bounds and required keys)."""

    @classmethod
    def from_spec(cls, spec: RheologySpec, density: float, reg: float | None) -> Rheology:
        """Build the rheology from the validated ``material.rheology`` block."""
        raise NotImplementedError

    def effective_viscosity(self, h: Array, u: Array, v: Array, grad_u: Array) -> Array:
        """``μ_eff`` [Pa s] per point, so that ``σ = 2 μ_eff D``."""
        raise NotImplementedError

    def stress(self, h: Array, u: Array, v: Array, grad_u: Array) -> Array:
        """Deviatoric stress ``σ = 2 μ_eff D`` [Pa] (seed eq. 3), shape (n, 2, 2), symmetric.

        ``σ_xx = 2 μ_eff ∂x u``, ``σ_yy = 2 μ_eff ∂y v``, ``σ_xy = μ_eff (∂y u + ∂x v)``.
        """
        mu_eff = self.effective_viscosity(h, u, v, grad_u)
        return 2.0 * mu_eff[:, None, None] * strain_rate(grad_u)

    def kinematic_stress(self, h: Array, u: Array, v: Array, grad_u: Array) -> Array:
        """``σ/ρ`` [m²/s²], the stress as it enters the momentum equation ``(1/ρ) ∇·(h σ)``."""
        return self.stress(h, u, v, grad_u) / self.density

    def max_effective_viscosity(self, h: Array, u: Array, v: Array, grad_u: Array) -> float:
        """Largest ``μ_eff`` [Pa s] over the nodes (0 for no node).

        For a spectral-radius bound of the explicit diffusion: the momentum diffuses with a
        kinematic viscosity of at most ``2 μ_eff/ρ`` (the ``σ_xx = 2 μ_eff ∂x u`` term). For
        :class:`Bingham` the bound ``μ + τ_Y/(2δ)`` holds whatever the state.
        """
        mu_eff = self.effective_viscosity(h, u, v, grad_u)
        return float(mu_eff.max()) if mu_eff.size else 0.0


class Bingham(Rheology):
    """Depth-integrated Bingham stress ``σ = (2μ + τ_Y/sqrt(I₂ + δ²)) D`` (seed eqs. 3-7).

    Case keys: ``viscosity`` and ``yield_stress`` (both required, >= 0).

    Attributes:
        viscosity: ``μ`` [Pa s].
        yield_stress: ``τ_Y`` [Pa].
        density: ``ρ`` [kg/m³] (for :meth:`kinematic_stress`).
        reg: ``δ`` [1/s], regularisation strain rate of the yield term.
        dry_tol: Depth [m] at or below which ``∂z v`` is taken as 0 (dry node).
    """

    name = "bingham"
    parameters = (
        Parameter("viscosity", "Bingham viscosity", "Pa s", ge=0.0, required=True),
        Parameter("yield_stress", "Bingham yield stress", "Pa", ge=0.0, required=True),
    )

    def __init__(
        self,
        viscosity: float,
        yield_stress: float,
        density: float,
        reg: float = REG_DEFAULT,
        dry_tol: float = 1e-6,
    ) -> None:
        if viscosity < 0 or yield_stress < 0 or density <= 0 or reg <= 0:
            raise ValueError("Bingham needs viscosity, yield_stress >= 0 and density, reg > 0")
        self.viscosity = float(viscosity)
        self.yield_stress = float(yield_stress)
        self.density = float(density)
        self.reg = float(reg)
        self.dry_tol = float(dry_tol)

    def __repr__(self) -> str:
        return (
            f"Bingham(viscosity={self.viscosity:g}, yield_stress={self.yield_stress:g}, "
            f"density={self.density:g}, reg={self.reg:g})"
        )

    def second_invariant(self, h: Array, u: Array, v: Array, grad_u: Array) -> Array:
        """``I₂ = ½ D̄ : D̄`` of the depth-averaged strain rate (seed eq. 5), with eqs. 6-7.

        Args:
            h: Depth [m], shape (n,).
            u: x-velocity [m/s], shape (n,).
            v: y-velocity [m/s], shape (n,).
            grad_u: (n, 2, 2) velocity gradient, ``grad_u[:, i, j] = ∂_j v_i``.

        Returns:
            ``I₂`` [1/s²], shape (n,).
        """
        h, u, v = (np.asarray(a, dtype=float) for a in (h, u, v))
        d = strain_rate(grad_u)
        wet = h > self.dry_tol
        hw = np.where(wet, h, 1.0)
        speed = np.hypot(u, v)
        psi = plug_ratio(speed, hw, self.viscosity, self.yield_stress)
        shear = np.where(wet, 3.0 / (2.0 + psi) / hw, 0.0)  # seed eq. 6: ∂z v = shear · v
        dzu, dzv = shear * u, shear * v
        d11, d22, d12 = d[:, 0, 0], d[:, 1, 1], d[:, 0, 1]
        full = d11**2 + d22**2 + 2.0 * d12**2 + 0.5 * (dzu**2 + dzv**2) + (d11 + d22) ** 2
        return 0.5 * full

    def effective_viscosity(self, h: Array, u: Array, v: Array, grad_u: Array) -> Array:
        """``μ_eff = μ + τ_Y / (2 sqrt(I₂ + δ²))`` [Pa s], so that ``σ = 2 μ_eff D``."""
        i2 = self.second_invariant(h, u, v, grad_u)
        return self.viscosity + 0.5 * self.yield_stress / np.sqrt(i2 + self.reg**2)

    @classmethod
    def from_spec(cls, spec: RheologySpec, density: float, reg: float | None = None) -> Bingham:
        """``Bingham(viscosity, yield_stress, density, reg)`` (``reg`` None: the default)."""
        extra = {} if reg is None else {"reg": reg}
        return cls(spec.viscosity, spec.yield_stress, density, **extra)


#: The rheologies, by name, in registration order (``law: none`` is not one of them).
RHEOLOGIES = Registry("rheology")
#: Add a :class:`Rheology` subclass to :data:`RHEOLOGIES` (its ``name`` must be new).
register_rheology = RHEOLOGIES.register

register_rheology(Bingham)


def rheology_from_spec(spec: RheologySpec, density: float,
                       reg: float | None = None) -> Rheology | None:
    """Build the rheology of a case: ``None`` for ``law: none``.

    Args:
        spec: The validated rheology block of the case.
        density: ``ρ`` [kg/m³].
        reg: Regularisation strain rate ``δ`` [1/s] of a yield term (None: the law's default).
    """
    if spec.law == "none":
        return None
    return RHEOLOGIES.get(spec.law).from_spec(spec, density, reg)
