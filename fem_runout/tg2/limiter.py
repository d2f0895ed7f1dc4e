"""The TG2-PC corrector's limiter: edge-based, bound-preserving, Lipschitz in the data.

One call of :meth:`Limiter.correction` turns the antidiffusive element contributions
``a[K, i] = dt (A_H - A_L)[K, i]`` of the owned cells into the nodal corrections
``m_i (Q_i^{n+1} - Q_i^L)`` that are added to the low-order (Rusanov) state ``Q^L``:

1. every cell's contributions are split into node-pair fluxes and a source
   (:func:`.fct.split_pairs`), each limited on its own (:func:`.fct.limit_pairs`);
2. the depth stays within the hydrostatic patch bounds of :func:`.fct.depth_candidates`
   (the free surface where wet, ``h >= 0`` always; a lake at rest has no room), the upper
   one relaxed at the shoreline (:data:`SHORE_SLACK`);
3. each momentum component stays within the patch extrema of the old and low-order momenta
   and of the low-order bar states (:func:`.low_order.bar_state_extrema`), relaxed by
   ``MOMENTUM_SLACK`` times their range;
4. synchronized (:func:`.fct.limit_pairs_sync`): the fluxes of ``h``, ``hu``, ``hv`` of a
   node pair share a factor, each variable's own weighted by how much of the pair's
   transport it carries, so mass does not move without its momentum nor momentum without
   its mass (synchronized FCT: Löhner et al. 1987, Kuzmin, Möller & Gurris 2012; Hajduk &
   Kuzmin 2022 limit the momentum with the depth's factor for the same reason);
5. near thin layers the momentum fluxes get no more than the depth's own (regularised)
   Zalesak ratio, through a continuous ramp (:meth:`Limiter.thin_cap`).

Every bound is a max/min over the full patch of a node (ghost cells included, reduced over
the ranks that share the node) and nothing switches on a threshold, so the step is
Lipschitz-continuous in the data and the same on any partition: a round-off difference
stays a round-off difference. This is the fully discrete, one-step counterpart of monotone
convex limiting (Hajduk & Kuzmin 2022, arXiv 2207.07261: bar states of the low-order
method, limiting of the well-balanced variables, momentum limited with the depth's factor
near dry areas), kept in the seed's predictor–corrector setting (eqs. 13–15).
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.active import ActiveSet
from fem_runout.mesh import Discretization
from fem_runout.tg2 import fct
from fem_runout.tg2.low_order import bar_state_extrema, pair_coefficients, pair_norms

#: Relaxation of the momentum bounds, as a fraction of their local range. Strict momentum
#: bounds clip the momentum peak of a dry-bed rarefaction (Ritter L1 0.139 → 0.216 at
#: dx = 0.25 m).
MOMENTUM_SLACK = 0.5

#: A node is "thin" when the shallowest node of its patch is below ``THIN_RATIO`` times the
#: deepest one (plus ``1e3 κ``); there its momenta follow the depth's limiting.
THIN_RATIO = 0.1

#: Relaxation of the depth's upper bound at the shoreline: ``SHORE_SLACK min(range, h^L_i)``
#: (``range`` the bound's local range), ramped by ``clip(1 - min_patch h^L / 1e3 κ, 0, 1)``
#: (1 where the patch has a dry node, 0 where it is all deeper than ``1e3 κ``). A run-up
#: raises the shoreline node's free surface above every wet neighbour's, which the patch bound
#: of the free surface forbids (the dry bank brings no candidate): Thacker's bowl lost 14–23 %
#: of accuracy to it (L1 at 80 cells 1.67e-3, now 1.44e-3; 1.36e-3 before issue 13).
#: Positivity stays (``h >= 0``) and a lake at rest has no range; Stoker, Ritter, Mangeney,
#: the hemisphere and the dam break are unchanged. Larger values amplify round-off in thin
#: layers: with 1 and no ``h^L_i`` cap the Coulomb pit kept a film moving at 1.5 m/s and
#: its 1e-14 continuity change grew to 2e-6; with 0.5 and the cap the cliff's reached 1e-9.
SHORE_SLACK = 0.25

#: Floor of ``P`` in the depth's sign-free ratio that caps thin-layer momenta, in ``m_i κ``.
#: It bounds the ratio's Lipschitz constant: with ``m_i κ`` the round-off at the draining
#: upstream end of the inclined dam break grew to a 1e-3 transverse spread (1e-11 with 10);
#: 100 held the dam-break tip back (front error 0.080 instead of 0.065 at 450 cells).
RATIO_FLOOR = 10.0


class Limiter:
    """Bounds and edge-based Zalesak limiting for (h, hu, hv) on one discretization.

    Args:
        disc: The discretization.
        gravity: Nodal gravity of the pressure term (``g``, or ``G`` of the slope form), an
            array the transport updates in place.
        kappa: Thin-layer depth κ [m] (regularisation of the thin-layer ratio).
    """

    def __init__(self, disc: Discretization, gravity: np.ndarray, kappa: float) -> None:
        self.disc = disc
        self.g = gravity
        self.kappa = float(kappa)
        #: depth under which a layer is thin whatever its neighbours (1e-3 h_max by default)
        self.thin_depth = 1e3 * self.kappa
        self.beta_all = pair_coefficients(disc.C)  # owned and ghost cells: whole patches
        self._key: tuple[int, int] | None = None
        self._arrays: dict[str, np.ndarray] = {}

    def _on(self, region: ActiveSet) -> dict[str, np.ndarray]:
        """Return the active cells' compact node rows, pair coefficients, masses, buffers."""
        key = (id(region), region.rebuilds)
        if key != self._key:
            n = region.owned.size
            self._arrays = {
                "owned": region.compact_cells("owned"),
                "local": region.compact_cells("cells"),
                "beta": np.ascontiguousarray(self.beta_all[region.cells]),
                "beta_norm": pair_norms(self.beta_all[region.cells]),
                "mass": self.disc.lumped_mass[region.nodes],
                "per_cell6": np.empty((n, 4, 6)), "per_cell3": np.empty((n, 4, 3)),
            }
            self._key = key
        return self._arrays

    def correction(self, q0: np.ndarray, q_low: np.ndarray, aec: np.ndarray, u: np.ndarray,
                   region: ActiveSet, bounds: tuple[np.ndarray, ...]) -> np.ndarray:
        """Limited corrections ``m_i (Q_i^{n+1} - Q_i^L)`` of (h, hu, hv) (collective).

        Synchronized (:func:`.fct.limit_pairs_sync`): each pair's fluxes of ``h``, ``hu``,
        ``hv`` share a factor weighted by their significance, on top of their own bounds.
        Nodal arrays are compact: row ``k`` is the active set's node ``region.nodes[k]``
        (every node of an active cell; the others are dry and get no correction).

        Args:
            q0: (n, 3) state at the start of the step.
            q_low: (n, 3) low-order state.
            aec: (n_active_owned, 4, 3) antidiffusive element contributions of the active
                owned cells (``region.owned``; the others contribute exact zeros).
            u: (2, n) desingularised nodal velocity of ``q0``.
            region: The active set (every node of an active cell has its whole patch in it,
                or a dry patch: the bounds are the whole mesh's).
            bounds: :meth:`finish_bounds` of this state's :meth:`local_extrema`, reduced
                over the ranks (the caller does that in an exchange of its own).

        Returns:
            (n, 3) compact corrections.
        """
        arrays = self._on(region)
        m = arrays["mass"]
        upper, lower, near, far = bounds
        n = region.owned.size
        flux, source = np.empty((3, n, 6)), np.empty((3, n))
        per_cell = arrays["per_cell6"]  # (P⁺, P⁻) of h, hu, hv: one exchange for the three
        fct.split_flux_sums(np.ascontiguousarray(aec), flux, source, per_cell)
        sums = region.cell_sum(per_cell)
        nn = m.shape[0]
        rplus, rminus, soft = np.empty((3, nn)), np.empty((3, nn)), np.empty(nn)
        # Zalesak's ratios, and the depth's sign-free ratio with P floored (continuous where
        # nothing flows)
        fct.synced_ratios(sums, m, upper, lower, q_low, m * self.kappa * RATIO_FLOOR, rplus,
                          rminus, soft)
        cap = np.maximum(self.thin_cap(near, far), soft)
        out = arrays["per_cell3"]
        fct.limit_pairs_sync(arrays["owned"], flux, source, rplus, rminus,
                             np.hypot(u[0], u[1]), cap, out)
        return region.cell_sum(out)

    def local_extrema(self, q0: np.ndarray, q_low: np.ndarray, z: np.ndarray, u: np.ndarray,
                      region: ActiveSet, extra: np.ndarray | None = None) -> np.ndarray:
        """Return this rank's eight patch extrema as maxima, (8, n) or (9, n) with ``extra``.

        Compact arrays, over the active cells' patches (whole patches, or dry ones). Rows:
        the maxima of h, hu, hv (states and bar states), the negated minima of the same, the
        maximum and the negated minimum of the low-order depth, then ``extra`` if given.
        Reduced over the ranks with one max exchange (minima as maxima of the negated values:
        exact) they give :meth:`finish_bounds`.
        """
        ext = np.empty((8 if extra is None else 9, q0.shape[0]))
        hi, lo = ext[0:3], ext[3:6]
        hi.fill(-np.inf)
        lo.fill(np.inf)
        far, near = ext[6], ext[7]
        far.fill(-np.inf)
        near.fill(np.inf)
        arrays = self._on(region)
        cells = arrays["local"]
        a, b = np.ascontiguousarray(q0.T), np.ascontiguousarray(q_low.T)
        fct.state_bounds(cells, a[0], a[1], a[2], b[0], b[1], b[2], z, hi, lo)
        g = self.g[region.nodes]
        speed = np.sqrt(g * np.maximum(a[0], 0.0))
        bar_state_extrema(cells, arrays["beta"], arrays["beta_norm"], a[0], u[0], u[1], z, g,
                          speed, hi[1:], lo[1:])
        fct.patch_extrema(cells, b[0], far, near)
        ext[3:6] *= -1.0
        ext[7] *= -1.0
        if extra is not None:
            ext[8] = extra
        return ext

    def finish_bounds(self, ext: np.ndarray, q_low: np.ndarray) -> tuple[np.ndarray, ...]:
        """Upper and lower bounds (n, 3), each containing the low-order state.

        From :meth:`local_extrema` reduced over the ranks. Also returns the patch minimum and
        maximum of the low-order depth (``near``, ``far``), the former relaxing the depth's
        upper bound at the shoreline (:data:`SHORE_SLACK`).
        """
        upper, lower = np.empty_like(q_low), np.empty_like(q_low)
        bounds_from_extrema(ext, q_low, self.thin_depth, MOMENTUM_SLACK, SHORE_SLACK, upper, lower)
        return upper, lower, -ext[7], ext[6]

    def thin_cap(self, near: np.ndarray, far: np.ndarray) -> np.ndarray:
        """Thin-layer ramp ``θ_i = clip(min_patch h^L / (1e3 κ + THIN_RATIO max_patch h^L))``.

        Where θ < 1 the momentum fluxes are capped by ``max(θ, R̃_h)``, ``R̃_h`` the depth's
        sign-free Zalesak ratio with ``P`` floored at ``RATIO_FLOOR m κ`` (continuous where
        nothing flows). Without it the momentum antidiffusion kept a draining rim node moving at
        3 m/s in a Coulomb pit; with an absolute threshold alone (``h < 1e3 κ``) a 4 mm
        layer on rough terrain reached 22 m/s (free-fall bound 21 m/s; 15 m/s with the
        relative ramp). The ramp replaces the former switch "a node of the cell is thinner
        than 1e3 κ". ``near``, ``far``: the patch extrema of :meth:`finish_bounds`.
        """
        out = np.empty(near.shape[0])
        thin_ramp(near, far, self.thin_depth, THIN_RATIO, out)
        return out


@numba.njit(cache=True)
def thin_ramp(near, far, thin_depth, ratio, out):
    """``out = clip(near / (thin_depth + ratio max(far, 0)), 0, 1)`` (NaN stays NaN)."""
    for i in range(out.shape[0]):
        f = far[i]
        f = f if (f > 0.0 or f != f) else 0.0  # np.maximum(f, 0.0), -0.0 included
        v = near[i] / (thin_depth + ratio * f)
        out[i] = 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)


@numba.njit(cache=True)
def bounds_from_extrema(ext, q_low, thin_depth, momentum_slack, shore_slack, upper, lower):
    """:meth:`Limiter.finish_bounds` per node in one pass (the array formulas' operations)."""
    for i in range(q_low.shape[0]):
        shore = min(max(1.0 - (-ext[7, i]) / thin_depth, 0.0), 1.0)
        hi, lo = ext[0, i], -ext[3, i]
        spread = hi - lo if hi > lo else 0.0  # ±inf where no active cell: no slack
        hi = hi + (shore_slack * shore) * min(spread, max(q_low[i, 0], 0.0))
        upper[i, 0], lower[i, 0] = max(hi, q_low[i, 0]), min(max(lo, 0.0), q_low[i, 0])
        for c in (1, 2):
            hi, lo = ext[c, i], -ext[3 + c, i]
            slack = momentum_slack * (hi - lo)
            upper[i, c], lower[i, c] = max(hi + slack, q_low[i, c]), min(lo - slack, q_low[i, c])
