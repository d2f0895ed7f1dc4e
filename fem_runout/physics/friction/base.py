"""The shared bed-friction machinery: the rate, the held-layer test and the implicit update.

Seed eq. 2 gives the bed friction force per unit area,
``B^f = -(ρ g h tanφ sgn v + ρ g |v|²/ξ) v/|v|``. The momentum equation (eq. 1) carries
``B^f/ρ`` (the reaction ``r`` of eq. 8). Every law of this package has the same two-term
form, acting on the momentum ``q = h v``::

    r(q) = -(g_c μ h sgn|v| + g_t k(h) |v|²) v/|v|,   v = q/h,

a **yield term** (Coulomb, ``μ = tanφ``; 0 for a law without a yield stress) and a
**drag term** with a per-node coefficient ``k(h)`` [s²/m] (:meth:`FrictionLaw.drag_coefficient`):
``1/ξ`` for Voellmy (seed eq. 2), 0 for Coulomb, ``n²/h^{1/3}`` for Manning. ``g_c = g_t = g``
in the seed's horizontal form. A law only states ``μ``, ``k`` and its parameters; the
evaluations below are shared.

* :meth:`FrictionLaw.rate` -- the explicit rate ``r(q)`` with the relaxed sign of seed eq. 20,
  ``sgn_γ(s) = clip(s/γ, -1, 1)``, applied to the speed ``|v|``. It vanishes at rest and is
  Lipschitz, which is what explicit evaluations need (the ``F_R^0`` and ``F_R^{j-2}`` terms of
  the IMEX-RKC stages, seed eq. 17).
* :meth:`FrictionLaw.implicit_update` -- the stage solve ``q - θ r(q) = q*`` of seed eq. 17
  (``θ = μ̃_1 Δt``), node by node, without any global matrix (below).

Implicit update
---------------
**Yield term, exact.** The sign of seed eq. 2 is set-valued at ``v = 0`` (``sgn 0 ∈ [-1, 1]``);
this is the limit ``γ → 0`` of seed eq. 20 and is what makes a layer stay at rest. If the
friction impulse can absorb all the momentum, ``|q*| <= θ g_c μ h`` (tested on the vector
magnitude), the solution is ``q = 0`` exactly: a layer under its yield stays at rest and a
decelerating flow stops, with no creep and no reversal. Otherwise the solution keeps the
direction ``n = q*/|q*|`` (friction antiparallel to ``v``) with ``0 < |q| < |q*|``. With the
relaxed sign alone, a resting layer under gravity would creep at a speed of order ``γ``. A
law without yield (``μ = 0``) moves whenever ``q* ≠ 0``: a layer on any slope starts moving.

**Per direction (seed §3.1.1).** Given ``n``, each direction ``i = x, y`` is a scalar equation,
solved by its own Newton iteration without inverting any matrix::

    G_i(q_i) = q_i + θ g_c μ h n_i + θ g_t k |q_i| q_i / (h² |n_i|) - q*_i = 0

(``|q| = |q_i|/|n_i|`` because ``q ∥ n``, so ``g_t k |v| v_i = g_t k |q_i| q_i/(h² |n_i|)``;
``h`` and so ``k(h)`` are frozen, the mass equation has no friction). ``G_i`` is increasing
and convex on the side of ``sgn q*_i``. Newton starts right of the root, at
``min(|R_i|, sqrt(|R_i|/a_i))`` (``R_i = q*_i - θ g_c μ h n_i``, ``a_i`` the quadratic
coefficient) or at the current momentum when that lies between the root and this bound, and
converges monotonically and quadratically (at most 6 iterations to ``|G_i| <= 1e-13 |q*_i|`` on
random states). Both directions give the same ``|q|``, so the friction stays collinear with
``v``.

**Slope-consistent form** (:mod:`fem_runout.physics.slope`). With a :class:`BedFrame` the law
acts on the bed: the yield stress ``μ σ_n`` with the bed-normal stress per unit mass
``g_N = g cosθ`` on the normal thickness ``h_n = h cosθ``, the drag ``ρ g k(h_n) |U|²`` with
the speed along the bed ``|U| = s |u|``, ``s = sqrt(1 + (n·∇Z)²)`` for the direction ``n`` of
motion; both act along ``-U``, whose horizontal part is ``-n/s`` per unit magnitude. Per unit
horizontal area on the horizontal momentum this is the same formula with ``g_c = g_N/s`` and
``g_t = g s/cosθ`` (:meth:`FrictionLaw.scales`; a block on a plane: ``μ g cos²θ``
horizontally, ``g (sinθ - μ cosθ)`` along the slope; a Voellmy sheet:
``|U|² = ξ h_n (sinθ - μ cosθ)``). ``n`` is the direction of ``q*`` in the implicit update
(friction is collinear with it), of ``v`` in the explicit rate.

**Over a whole step** (:meth:`FrictionLaw.integrate`). The friction ODE ``dq/dt = r(q)`` is
advanced by Alexander's two-stage SDIRK (stiffly accurate, L-stable, second order), each stage
one :meth:`FrictionLaw.implicit_update` with ``θ = γ_s Δt``, ``γ_s = 1 - 1/√2``; the second
stage's right-hand side ``q + (1-γ_s)/γ_s (Q_1 - q)`` is clamped at zero along ``q`` (the
exact flow never reverses). Exact for the yield term alone (a constant deceleration): the flow
stops if and only if ``|q| <= Δt g_c μ h``, as one backward-Euler solve over ``Δt``; second
order for the drag. One backward-Euler solve is first order: Strang's splitting around it
(TG2-PC) was first order overall, 1.4e-2 relative error of the Voellmy sheet's speed at 100
steps where this gives 3.5e-5 (docs/method.md).

**Where γ is used.** Once the sign is resolved by the yield test the residual is smooth (the
semi-smooth Newton of seed §3.1.1 reduces to Newton) and ``γ`` is not needed by the implicit
update. It is used by :meth:`FrictionLaw.rate`, the explicit evaluation, as seed eq. 20 says.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from fem_runout.physics.friction.registry import Parameter, ParameterError

if TYPE_CHECKING:
    from fem_runout.config.schema import FrictionSpec
    from fem_runout.physics.slope import BedFrame

__all__ = [
    "GAMMA",
    "GAMMA_DEFAULT",
    "MU",
    "PHI_DEG",
    "FrictionLaw",
    "check_one_coulomb_key",
    "coulomb_coefficient",
    "relaxed_sign",
    "spend_capacity",
]

Array = np.ndarray

#: Newton stops once every residual is below ``NEWTON_RTOL`` times its scale.
NEWTON_RTOL = 1e-13
#: Upper bound on Newton iterations (5-6 are typical, see :meth:`FrictionLaw.implicit_update`).
NEWTON_MAX_ITER = 50

#: ``γ_s = 1 - 1/√2`` of Alexander's two-stage SDIRK (:meth:`FrictionLaw.integrate`).
SDIRK_GAMMA = 1.0 - 1.0 / math.sqrt(2.0)

#: Coulomb friction coefficient ``μ = tanφ`` of seed eq. 2 (or give :data:`PHI_DEG`).
MU = Parameter("mu", "friction coefficient", ge=0.0)
#: Friction angle ``φ`` of seed eq. 2; ``μ = tan φ``.
PHI_DEG = Parameter("phi_deg", "friction angle; mu = tan(phi_deg)", "deg", ge=0.0, lt=90.0)
#: Default relaxation ``γ`` of the sign [m/s], seed eq. 20: written here and nowhere else (the
#: schema fills it in from :data:`GAMMA`, the laws' signatures use this name).
GAMMA_DEFAULT = 1e-2
#: Relaxation ``γ`` of the sign, seed eq. 20.
GAMMA = Parameter("gamma", "relaxation of the sign function (seed eq. 20)", "m/s", gt=0.0,
                  default=GAMMA_DEFAULT)


def relaxed_sign(s: Array, gamma: float) -> Array:
    """Relaxed sign function of seed eq. 20: ``sgn_γ(s) = clip(s/γ, -1, 1)``."""
    return np.clip(np.asarray(s, dtype=float) / gamma, -1.0, 1.0)


def coulomb_coefficient(mu: float | None, phi_deg: float | None) -> float:
    """``μ`` of seed eq. 2 from ``mu`` or ``phi_deg`` (``tan φ``), whichever is given."""
    if mu is not None:
        return mu
    assert phi_deg is not None
    return math.tan(math.radians(phi_deg))


def check_one_coulomb_key(name: str, given: Mapping[str, Any]) -> None:
    """Raise :class:`ParameterError` unless exactly one of ``mu`` and ``phi_deg`` is given."""
    if (given.get("mu") is None) == (given.get("phi_deg") is None):
        raise ParameterError(f"law '{name}' needs exactly one of mu or phi_deg")


def spend_capacity(qx: Array, qy: Array, rest: Array) -> tuple[Array, Array]:
    """``q max(0, 1 - rest/|q|)``: the yield test with the capacity ``rest`` left (no mask).

    See :meth:`FrictionLaw.unused_capacity`; moving nodes have ``rest = 0`` and keep ``q``.
    """
    norm = np.hypot(qx, qy)
    keep = np.where(norm > rest, 1.0 - rest / np.where(norm > 0.0, norm, 1.0), 0.0)
    return qx * keep, qy * keep


class FrictionLaw:
    """Bed friction ``r(q) = -(g_c μ h sgn|v| + g_t k(h) |v|²) v/|v|`` (seed eq. 2 form).

    A law subclasses this and sets what is its own: ``name`` and ``parameters`` (its keys in
    the case), ``μ`` (passed to this constructor; 0 for no yield stress),
    :meth:`drag_coefficient` and :meth:`from_spec` (and :meth:`check_parameters` if its keys
    depend on each other). The rate, the yield test and the Newton update are shared.

    Args:
        mu: Coulomb friction coefficient ``tanφ`` [-] (0: no yield stress).
        gravity: Gravitational acceleration ``g`` [m/s²].
        gamma: Relaxation of the sign, seed eq. 20 [m/s] (used by :meth:`rate` only).
        dry_tol: Depth [m] at or below which a node is dry (no momentum, no friction).

    Attributes:
        name: Key in case files (``material.friction.law``).
        parameters: The law's other keys in ``material.friction``.
    """

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()

    def __init__(self, mu: float, gravity: float, gamma: float = GAMMA_DEFAULT,
                 dry_tol: float = 1e-6) -> None:
        if mu < 0 or gravity <= 0 or gamma <= 0 or dry_tol < 0:
            raise ValueError("friction needs mu >= 0, g > 0, gamma > 0, dry_tol >= 0")
        self.mu = float(mu)
        self.gravity = float(gravity)
        self.gamma = float(gamma)
        self.dry_tol = float(dry_tol)

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v:g}" for k, v in self._shown().items())
        return f"{type(self).__name__}({shown})"

    def _shown(self) -> dict[str, float]:
        """Return the values :meth:`__repr__` shows."""
        return {"mu": self.mu, "g": self.gravity, "gamma": self.gamma}

    # -- what a law provides ------------------------------------------------------------------
    def drag_coefficient(self, h: Array, bed: BedFrame | None) -> Array | float:
        """``k(h)`` [s²/m] of the drag ``g_t k |v|²``: a float or one value per node.

        ``h`` is the vertical depth (wet nodes; dry ones hold 1.0). On a bed a law uses the
        slope-normal thickness ``h_n = h bed.cos``. Default: no drag (0).
        """
        return 0.0

    @classmethod
    def check_parameters(cls, given: Mapping[str, Any]) -> None:
        """Check the keys ``given`` (non-None) against each other; raise :class:`ParameterError`.

        Bounds, unknown and required keys are checked by the registry; this is for the rest.
        """

    @classmethod
    def from_spec(cls, spec: FrictionSpec, gravity: float, dry_tol: float) -> FrictionLaw:
        """Build the law from the validated ``material.friction`` block of a case."""
        raise NotImplementedError

    @property
    def has_yield(self) -> bool:
        """Whether the law has a yield stress (a layer can stay at rest on a slope)."""
        return self.mu > 0.0

    # -- shared machinery ---------------------------------------------------------------------
    def scales(self, bed: BedFrame | None, nx: Array, ny: Array) -> tuple[Array | float, ...]:
        """``(g_c, g_t)``: the gravity of the yield and the drag term for direction n.

        ``(g, g)`` in the seed's horizontal form (``bed`` None); on a bed
        ``(g_N/s, g s/cosθ)`` with ``s = sqrt(1 + (n·∇Z)²)`` (module docstring).
        """
        if bed is None:
            return self.gravity, self.gravity
        s = bed.stretch(nx, ny)
        return bed.normal / s, self.gravity * s / bed.cos

    def yield_impulse(self, h: Array, qx: Array, qy: Array, dt: float,
                      bed: BedFrame | None = None) -> Array:
        """Coulomb impulse ``dt μ g_c h`` a node can absorb in ``dt``.

        On a bed the direction is that of ``q``, or straight down the slope at rest (where
        a layer at rest would start to move).
        """
        if bed is None:
            return dt * self.gravity * self.mu * np.maximum(h, 0.0)
        norm = np.hypot(qx, qy)
        down = bed.downhill()
        safe = np.where(norm > 0.0, norm, 1.0)
        nx = np.where(norm > 0.0, qx / safe, down[:, 0])
        ny = np.where(norm > 0.0, qy / safe, down[:, 1])
        gc, _ = self.scales(bed, nx, ny)
        return dt * gc * self.mu * np.maximum(h, 0.0)

    def unused_capacity(self, h: Array, qx: Array, qy: Array, dt: float,
                        bed: BedFrame | None = None) -> Array | None:
        """``max(0, dt μ g_c h - |q|)``: the yield impulse left after stopping ``q`` (or None).

        Strang's splitting ``F(dt/2) D(dt) F(dt/2)`` of a force ``F`` and the friction ``D``
        gives a layer at rest on a slope the force's second half after ``D`` stopped it. ``D``
        had the whole step's capacity and used ``|q|`` of it; what is left holds that half
        (:func:`spend_capacity`). None for a law without yield stress.
        """
        if not self.has_yield:
            return None
        return np.maximum(self.yield_impulse(h, qx, qy, dt, bed) - np.hypot(qx, qy), 0.0)

    def rate(self, h: Array, qx: Array, qy: Array,
             bed: BedFrame | None = None) -> tuple[Array, Array]:
        """Explicit friction rate ``r(q)`` (seed eq. 2 form) with the relaxed sign of eq. 20.

        ``r = -(g_c μ h sgn_γ(|v|) + g_t k |v|²) v/|v|`` with ``v = q/h``; zero on dry nodes
        and at rest. For ``|v| < γ`` the yield part is ``-g μ h v/γ`` (linear), so ``r`` is
        Lipschitz and always antiparallel to ``v``.

        Args:
            h: Depth [m], shape (n,).
            qx: x-momentum ``h u`` [m²/s], shape (n,).
            qy: y-momentum ``h v`` [m²/s], shape (n,).
            bed: The bed under the nodes (slope-consistent form), or None (seed's form).

        Returns:
            ``(rx, ry)`` [m²/s²], shape (n,).
        """
        h, qx, qy = (np.asarray(a, dtype=float) for a in (h, qx, qy))
        wet = h > self.dry_tol
        hw = np.where(wet, h, 1.0)
        ux, uy = qx / hw, qy / hw
        speed = np.hypot(ux, uy)
        moving = np.where(speed > 0.0, speed, 1.0)
        gc, gt = self.scales(bed, ux / moving, uy / moving)
        k = self.drag_coefficient(hw, bed)
        # -(g μ h sgn_γ(|v|)/|v| + g k |v|) v, with sgn_γ(|v|)/|v| = 1/max(|v|, γ)
        coef = gc * self.mu * hw / np.maximum(speed, self.gamma) + gt * k * speed
        coef = np.where(wet, coef, 0.0)
        return -coef * ux, -coef * uy

    def implicit_update(
        self,
        h: Array,
        qx: Array,
        qy: Array,
        qx_star: Array,
        qy_star: Array,
        dt_mu: float,
        bed: BedFrame | None = None,
    ) -> tuple[Array, Array]:
        """Solve the implicit stage equation ``q - θ r(q) = q*`` node by node (seed eq. 17).

        ``θ = dt_mu = μ̃_1 Δt`` and ``h`` is frozen (the mass equation has no friction). The
        yield sign is resolved exactly (``q = 0`` if ``|q*| <= θ g_c μ h``, else ``q ∥ q*``),
        then each direction is solved by its own scalar Newton iteration; see "Implicit
        update" in the module docstring.

        Args:
            h: Depth [m], shape (n,).
            qx: Current x-momentum [m²/s] (Newton initial guess only), shape (n,).
            qy: Current y-momentum [m²/s] (Newton initial guess only), shape (n,).
            qx_star: x-component of the right-hand side ``q*`` [m²/s], shape (n,).
            qy_star: y-component of the right-hand side ``q*`` [m²/s], shape (n,).
            dt_mu: ``θ = μ̃_1 Δt`` [s], >= 0.
            bed: The bed under the nodes (slope-consistent form), or None (seed's form).

        Returns:
            ``(qx_new, qy_new)``; zero on dry nodes (``h <= dry_tol``) and below the yield.

        Raises:
            FloatingPointError: If Newton does not converge (it should not happen).
        """
        h, qx, qy, sx, sy = (np.asarray(a, dtype=float) for a in (h, qx, qy, qx_star, qy_star))
        wet = np.flatnonzero(h > self.dry_tol)
        if wet.size == h.size:
            return self._update_wet(h, qx, qy, sx, sy, float(dt_mu), bed)
        # the work is per node: only the wet nodes (where the flow is) are solved, the same bits
        out_x, out_y = np.zeros_like(h), np.zeros_like(h)
        out_x[wet], out_y[wet] = self._update_wet(
            h[wet], qx[wet], qy[wet], sx[wet], sy[wet], float(dt_mu),
            None if bed is None else bed.take(wet))
        return out_x, out_y

    def integrate(self, h: Array, qx: Array, qy: Array, dt: float,
                  bed: BedFrame | None = None) -> tuple[Array, Array]:
        """Advance ``dq/dt = r(q)`` by ``dt`` from ``q``, node by node (module docstring).

        Two :meth:`implicit_update` stages with ``θ = γ_s dt`` (Alexander's SDIRK); the second
        stage starts from ``max(0, 1 + (1-γ_s)/γ_s (|Q_1|/|q| - 1)) q``: exact for the yield
        term, second order for the drag, continuous in the data. Compiled as one pass over
        the nodes (:mod:`fem_runout.physics.friction.integrate_kernel`), with the same bits
        as the two stages (tested).

        Args:
            h: Depth [m] (frozen over the step), shape (n,).
            qx: x-momentum at the start [m²/s], shape (n,).
            qy: y-momentum at the start [m²/s], shape (n,).
            dt: Step [s], >= 0.
            bed: The bed under the nodes (slope-consistent form), or None (seed's form).

        Returns:
            ``(qx, qy)`` after ``dt``, parallel to the start's momentum and not longer.
        """
        from fem_runout.physics.friction.integrate_kernel import integrate_nodes  # compiled

        h = np.asarray(h, dtype=float)
        k = self.drag_coefficient(np.where(h > self.dry_tol, h, 1.0), bed)
        return integrate_nodes(h, qx, qy, dt, SDIRK_GAMMA, self.mu, self.gravity, self.dry_tol,
                               k, bed, NEWTON_RTOL, NEWTON_MAX_ITER)

    def integrate_in_stages(self, h: Array, qx: Array, qy: Array, dt: float,
                            bed: BedFrame | None = None) -> tuple[Array, Array]:
        """:meth:`integrate` as its two :meth:`implicit_update` stages (the reference)."""
        theta = SDIRK_GAMMA * dt
        ax, ay = self.implicit_update(h, qx, qy, qx, qy, theta, bed)
        norm = np.hypot(qx, qy)
        ratio = np.hypot(ax, ay) / np.where(norm > 0.0, norm, 1.0)
        f = np.maximum(1.0 + (1.0 - SDIRK_GAMMA) / SDIRK_GAMMA * (ratio - 1.0), 0.0)
        return self.implicit_update(h, ax, ay, f * qx, f * qy, theta, bed)

    def _update_wet(self, h: Array, qx: Array, qy: Array, sx: Array, sy: Array, theta: float,
                    bed: BedFrame | None) -> tuple[Array, Array]:
        """:meth:`implicit_update` on nodes that may be dry or wet (the formula itself)."""
        wet = h > self.dry_tol
        hw = np.where(wet, h, 1.0)
        norm = np.hypot(sx, sy)
        unit = np.where(norm > 0.0, norm, 1.0)
        gc, gt = self.scales(bed, sx / unit, sy / unit)
        k = self.drag_coefficient(hw, bed)
        moving = wet & (norm > theta * gc * self.mu * hw)
        safe = np.where(moving, norm, 1.0)
        out = []
        for star, guess in ((sx, qx), (sy, qy)):
            n_i = np.where(moving, star / safe, 0.0)
            out.append(self._solve_direction(hw, star, guess, n_i, theta, moving, gc, gt, k))
        return out[0], out[1]

    def _solve_direction(
        self, h: Array, star: Array, guess: Array, n_i: Array, theta: float, moving: Array,
        gc: Array | float, gt: Array | float, k: Array | float,
    ) -> Array:
        """Newton solve of ``x + a |x| x = R`` for one direction (see :meth:`implicit_update`).

        ``gc``, ``gt``: gravity of the yield and drag terms (:meth:`scales`); ``k``: the drag
        coefficient (:meth:`drag_coefficient`).
        """
        from fem_runout.physics.friction.newton import solve_direction  # compiled

        # one compiled pass: each node stops at its own convergence, so its result does not
        # depend on which other nodes share its rank (the same bits on any partition)
        return solve_direction(h, star, guess, n_i, moving, gc, gt, k, theta, self.mu,
                               NEWTON_RTOL, NEWTON_MAX_ITER)
