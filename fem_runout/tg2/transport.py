"""The TG2-PC transport operator: DG0 predictor, Q1 corrector, Rusanov low order, Zalesak FCT.

One call of :meth:`Transport.step` advances ``(h, hu, hv)`` on the Q1 nodes by ``dt`` for
``∂_t q + ∇·F(q) + B(q)∇Z = 0`` (seed eqs. 8–15):

1. nodal velocity and the per-cell free surface η̃ (numba);
2. predictor into DG0 (UFL form, eq. 10 first line);
3. corrector element contributions A_H[K, i] (UFL form on discontinuous Q1, eqs. 10–12);
4. low-order Rusanov element contributions A_L[K, i] (numba, :mod:`.low_order`);
5. the edge-based, bound-preserving limiter of :mod:`.limiter` (depth within hydrostatic
   patch bounds, momenta within the patch's and the bar states' bounds), Lipschitz in the
   data; ``m_i Q^{n+1} = m_i Q^L + Σ_K (Σ_j f*_ij + μ*_i)``; then the speed bound of
   :func:`.bounds.bound_speed` (Riemann invariant plus bed drop, continuous weights);
6. boundary fluxes (open: outflow with the node's own state; wall: zero normal momentum);
7. films thinner than the dry tolerance dry out continuously (:func:`.compact.dry_films`).
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fem_runout.active import ActiveSet
from fem_runout.config.schema import STEP_BOUNDS
from fem_runout.mesh import Discretization, GhostReducer, zero_wall_normal
from fem_runout.physics.slope import SlopeGeometry
from fem_runout.stepping import acceleration_limit
from fem_runout.tg2 import bounds
from fem_runout.tg2.compact import (
    antidiffusive,
    dry_films,
    gather_state,
    low_state,
    min_ratio,
    new_state,
    scatter_state,
    settle,
    wet_weighted_max,
)
from fem_runout.tg2.high_order import HighOrder
from fem_runout.tg2.limiter import Limiter
from fem_runout.tg2.low_order import low_order_pass, pair_norms, velocity_on
from fem_runout.tg2.mass_correction import MassCorrection

#: Width, in units of κ, of the wet weight that scales the slope of the time-step limit.
WET_DEPTH = 1e3


class Transport:
    """TG2-PC + FCT transport on a :class:`Discretization`.

    Args:
        disc: The discretization.
        gravity: g [m/s²].
        dry_tolerance: Depth under which a node counts as dry [m].
        thin_depth: Depth κ under which velocities are desingularised [m].
        fct_enabled: Blend with the low-order scheme (True) or use raw TG2-PC (False).
        slope: Bed geometry of the slope-consistent form (``g`` in ``g h ∇η`` and the wave
            speeds becomes ``G = cos²θ max(g + u·H·u, 0)``), or None for the seed's form.
        active_set: Work on the cells near the flow only (the same bits as all cells).
        mass_correction: Add the gated consistent-mass correction to the corrector
            (:mod:`fem_runout.tg2.mass_correction`); False gives the seed's lumped corrector.
        step_bound: ``"conservative"`` or ``"positivity"``: the time-step bound of
            :meth:`stable_dt`.
    """

    def __init__(
        self,
        disc: Discretization,
        gravity: float,
        dry_tolerance: float,
        thin_depth: float,
        fct_enabled: bool = True,
        slope: SlopeGeometry | None = None,
        active_set: bool = True,
        mass_correction: bool = True,
        step_bound: str = "conservative",
    ) -> None:
        if step_bound not in STEP_BOUNDS:
            raise ValueError(f"step_bound must be one of {STEP_BOUNDS}, got {step_bound!r}")
        self.disc = disc
        #: capacities with the signed advective part (the depth's own bound, stable_dt)
        self.signed_capacity = step_bound == "positivity"
        self.g = float(gravity)
        self.slope = slope
        #: nodal gravity of the pressure term: g, or G of the slope form (updated per pass)
        self.gn = np.full(disc.coords.shape[0], self.g)
        self.tol = float(dry_tolerance)
        self.kappa = max(float(thin_depth), self.tol)
        #: width of the wet weight min(1, h/δ) of the slope time-step limit
        self.wet_depth = WET_DEPTH * self.kappa
        self._slope: np.ndarray | None = None
        self.fct_enabled = fct_enabled
        V = disc.V
        self.h, self.hu, self.hv, self.z = (fem.Function(V, name=n) for n in ("h", "hu", "hv", "z"))
        self.ux, self.uy = fem.Function(V), fem.Function(V)
        # views of the functions' arrays, taken once (each ``x.array`` builds a new view)
        self._h, self._hu, self._hv, self._z, self._ux, self._uy = (
            f.x.array for f in (self.h, self.hu, self.hv, self.z, self.ux, self.uy))
        self.high = HighOrder(disc, (self.h, self.hu, self.hv), (self.ux, self.uy), self.z,
                              self.g, self.kappa, slope is not None)
        self.reducer = GhostReducer(disc)
        #: where the step works: the cells near the flow (or, without the active set, all)
        self.active = ActiveSet(disc, self.reducer)
        self.active_set = active_set
        self.limiter = Limiter(disc, self.gn, self.kappa)
        self.mass_correction = MassCorrection(disc, self.kappa) if mass_correction else None
        self.outflow_volume = 0.0
        #: volume of the films that dried out so far (:func:`.compact.dry_films`) [m³]
        self.dried_volume = 0.0
        self._beta = self.limiter.beta_all
        self._fresh = False  # low-order rates of the current state are cached
        self._dt = 0.0  # the step being taken
        self._anywhere = True  # the state was set on every node (not just the set's)
        #: the active set's test of the state, over the ranks, and the set it was made on
        #: (sent with the step's last exchange, :meth:`_finalise`; None: test in the pass)
        self._inside: tuple[bool, int] | None = None
        self._sums = np.empty((0, 4))  # nodal sums of the low-order rates and capacities
        self._active_key, self._on = -1, {}

    # -- state -----------------------------------------------------------------------------
    def state(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n_nodes_local, 3) copy of (h, hu, hv), into ``out`` if it has that shape."""
        arrays = [self._h, self._hu, self._hv]
        if out is None or out.shape != (arrays[0].size, 3):
            out = np.empty((arrays[0].size, 3))
        return np.stack(arrays, axis=1, out=out)

    def flow_nodes(self) -> np.ndarray | None:
        """Local nodes outside which the state is exactly zero (the active set's), or None.

        None when that is not known: without the active set, or after :meth:`set_state`
        until the next low-order pass has fitted the set to the new state.
        """
        return self.active.nodes if self.active_set and not self._anywhere else None

    def state_on(self, nodes: np.ndarray) -> np.ndarray:
        """(len(nodes), 3) copy of (h, hu, hv) at the local nodes ``nodes``."""
        return gather_state(self._h, self._hu, self._hv,
                             np.asarray(nodes), np.empty((len(nodes), 3)))

    def set_state_on(self, nodes: np.ndarray, q: np.ndarray, depth_kept: bool = False) -> None:
        """Set (h, hu, hv) at the local nodes ``nodes`` (the others keep their values).

        ``depth_kept``: the depth is that of the state the step left, and the momenta are
        still zero where it is (a node-wise friction step): the active set's test sent with
        that step holds for the new state.
        """
        scatter_state(self._h, self._hu, self._hv, np.asarray(nodes),
                       np.asarray(q, dtype=np.float64))
        self._fresh = False
        if not depth_kept:
            self._inside = None

    def set_state(self, q: np.ndarray) -> None:
        """Set (h, hu, hv) from a (n_nodes_local, 3) array (ghosts included)."""
        self._h[:], self._hu[:], self._hv[:] = q[:, 0], q[:, 1], q[:, 2]
        self._fresh = False
        self._anywhere = True
        self._inside = None

    # -- time step ---------------------------------------------------------------------------
    def stable_dt(self, with_slope: bool = False) -> float | tuple[float, float]:
        """Largest dt for which the low-order update keeps h >= 0 (CFL number 1).

        ``dt = min_i m_i / (Σ_j (d_ij + |β_ij·u_i|) + Σ_open w_i max(u_i·n, 0))``, with the
        eigenvalues ``|u·n| + sqrt(g h)`` of the full system in ``d_ij``. With
        ``step_bound="positivity"`` the sum takes ``β_ij·u_i`` with its sign: the largest step
        for which the low-order depth stays non-negative (node i loses ``h*_ij (d_ij +
        β_ij·u_i)`` to each pair, ``h*_ij <= h_i``), up to twice as long in a fast flow, where
        the advective parts cancel (``Σ_j β_ij = 0``); :mod:`fem_runout.tg2.low_order`. The
        low-order rates of the same pass are kept for the next :meth:`step`.

        Args:
            with_slope: Also return the slope-acceleration limit (one reduction for both):
                ``sqrt(Δx / (g S_max))``, ``S_max`` the steepest bed slope at a wet node, so
                that a layer starting at rest on the slope moves at most half a cell in one
                step. The wave speed alone (``sqrt(g h)``) allowed a 3 s step to a 1e-4 m
                film on a slope and a 6 s one to a layer at rest on 40°.

        Returns:
            The CFL limit, or ``(CFL limit, acceleration limit)``.
        """
        local = self.local_limits(with_slope)
        self.disc.comm.Allreduce(MPI.IN_PLACE, local, op=MPI.MAX)
        return self.limits_from(local, with_slope)

    def local_limits(self, with_slope: bool = True) -> np.ndarray:
        """Return this rank's part of :meth:`stable_dt`, to be maximised over the ranks.

        Returns ``[-dt, S]`` (minus the CFL limit, so that a max reduction gives the minimum
        exactly; the weighted steepest slope, 0 without ``with_slope``). Collective: the
        low-order pass sums over the ranks' shared nodes.
        """
        a = self.active
        self._low_order_pass()
        cap = self._sums[:, 3].copy()
        nodes = a.nodes
        for side in a.sides():
            if side.kind == "open" and side.nodes.size:
                i = nodes[side.nodes]
                un = self.ux.x.array[i] * side.normal[:, 0] + self.uy.x.array[i] * side.normal[:, 1]
                cap[side.nodes] += side.weight * np.maximum(un, 0.0)
        ratio = min_ratio(self._arrays()["mass"], cap, a.n_owned_nodes)
        return np.array([-ratio, self._local_slope() if with_slope else 0.0])

    def limits_from(self, top: np.ndarray, with_slope: bool = True
                    ) -> float | tuple[float, float]:
        """:meth:`stable_dt` from the ranks' maxima of :meth:`local_limits`."""
        if not with_slope:
            return -float(top[0])
        return -float(top[0]), acceleration_limit(self.disc.min_cell_size, self.g, float(top[1]))

    def _local_slope(self) -> float:
        """Steepest bed slope at this rank's owned nodes, weighted by ``min(1, h/δ)``.

        The ``Z`` slope is computed once: the patch maximum of the cell-mean gradients.
        """
        if self._slope is None:
            self._slope = bounds.node_slopes(self.disc, self.z.x.array, self.reducer)
        # the continuous wet weight min(1, h/δ) of the owned nodes
        return float(wet_weighted_max(self._h, self._slope, self.wet_depth,
                                      self.disc.n_owned_nodes))

    def _low_order_pass(self) -> None:
        """Velocity, low-order rates A_L and capacities of the state, on the active set."""
        if self.active_set:  # dry cells give exact zeros: visit the active ones only
            # the last step's test over the ranks, if made on this set (else None: test here)
            known = self._inside[0] if self._inside is not None \
                and self._inside[1] == self.active.rebuilds else None
            if self._anywhere:  # set by set_state: the flow may be anywhere
                self.active.update(self.state())
            elif not known:  # the step wrote the set's nodes only; inside: nothing to do
                self.active.update(self.state_on(self.active.nodes), self.active.nodes, known)
            self._anywhere = False
        on = self._arrays()
        nodes = on["nodes"]
        h, hu, hv, z = self._h, self._hu, self._hv, self._z
        ux, uy = on["u"]  # the set's velocities: the next step's (compact, (2, n))
        velocity_on(h, hu, hv, nodes, self.kappa, self._ux, self._uy, ux, uy)
        if self.slope is not None:
            self.gn[nodes] = on["slope"].pressure_gravity(ux, uy)
        low_order_pass(on["cells"], on["beta"], on["beta_norm"], on["C"], h, hu, hv, z,
                       self._ux, self._uy, self.gn, self.kappa, on["lo"],
                       on["cap"], self.signed_capacity)
        # nodal sums of the rates and of the capacities in one exchange
        self._sums = self.active.cell_sum(on["lo_cap"])
        self._fresh = True

    def _arrays(self) -> dict[str, object]:
        """Return the active set's arrays, cached until it is rebuilt.

        The active owned cells' nodes, pair and ``C`` coefficients, their low-order rates
        ``A_L`` and capacities of the current state (``lo``, ``cap``), and the compact nodes,
        lumped mass, bed and slope geometry of the set's nodes.
        """
        if self._active_key != self.active.rebuilds:
            idx, nodes = self.active.owned, self.active.nodes
            self._on = {
                "cells": np.ascontiguousarray(self.disc.cell_nodes[idx]),
                "beta": np.ascontiguousarray(self._beta[idx]),
                "beta_norm": np.ascontiguousarray(pair_norms(self._beta[idx])),
                "C": np.ascontiguousarray(self.disc.C[idx]),
                "lo_cap": np.empty((idx.size, 4, 4)), "aec": np.empty((idx.size, 4, 3)),
                "u": np.empty((2, nodes.size)),
                "nodes": nodes, "mass": self.disc.lumped_mass[nodes],
                "z": self.z.x.array[nodes],
                "slope": None if self.slope is None else self.slope.take(nodes),
            }
            # the rates A_L and the capacities are views of one array: summed together
            self._on["lo"], self._on["cap"] = self._on["lo_cap"][:, :, :3], \
                self._on["lo_cap"][:, :, 3]
            self._active_key = self.active.rebuilds
        return self._on

    def step(self, dt: float) -> None:
        """Advance (h, hu, hv) by ``dt`` on the active set (compact arrays; dry elsewhere)."""
        self._dt = float(dt)
        if not self._fresh:
            self._low_order_pass()
        # the low-order pass of this state (here or in stable_dt) updated the active set
        a = self.active
        high = self.high.contributions(a, None if self.slope is None else self.gn, dt)
        arrays = self._arrays()
        m, z = arrays["mass"], arrays["z"]
        nodes = a.nodes
        q0 = self.state_on(nodes)
        u = arrays["u"]  # of q0: the low-order pass of this state wrote them
        boundary = self._boundary_flux(q0, u)
        q_low = low_state(q0, self._sums, boundary, m, self._dt)
        aec = antidiffusive(high, arrays["lo"], dt, arrays["aec"])
        # the limiter's patch extrema and the speed bound (maxima over the ranks) travel in the
        # mass correction's exchange
        gn = self.gn[nodes]
        smax = self._patch_speed(q_low, z, gn)
        ext = self.limiter.local_extrema(q0, q_low, z, u, a, smax) if self.fct_enabled \
            else smax[np.newaxis]
        if self.mass_correction is not None:
            self.mass_correction.add(aec, high, dt * boundary, q0[:, 0], m, a, also_max=ext)
        else:
            a.reducer.reduce(ext, "max")
        if self.fct_enabled:
            corr = self.limiter.correction(q0, q_low, aec, u, a,
                                           self.limiter.finish_bounds(ext, q_low))
        else:
            corr = a.cell_sum(aec)
        q_new = new_state(q_low, corr, m)
        bounds.bound_speed(q_low, q_new, ext[-1], gn)
        inside = self._finalise(q_new, q0, u, m)
        self.set_state_on(nodes, q_new)
        self._inside = (inside, a.rebuilds)

    # -- pieces ------------------------------------------------------------------------------
    def _boundary_flux(self, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Open sides: outflow ``-w_i F(U_i)·n⁺``; nothing enters; walls take nothing through.

        Material leaves through an open side with the node's own state (non-reflecting for
        outgoing flow). Nothing enters: with the zero-gradient state an inflowing node gains
        mass and momentum in proportion to ``q |u·n|``, a feedback that blew up at the open
        sides of the inclined dam break, and a run-out domain has nothing outside to bring in.
        Compact arrays (the set's nodes).
        """
        flux = np.zeros_like(q)
        for side in self.active.sides():
            if side.kind != "open" or not side.nodes.size:
                continue
            i = side.nodes
            un = np.maximum(u[0, i] * side.normal[:, 0] + u[1, i] * side.normal[:, 1], 0.0)
            w = side.weight
            flux[i, 0] -= w * q[i, 0] * un
            flux[i, 1] -= w * q[i, 1] * un
            flux[i, 2] -= w * q[i, 2] * un
        return flux

    def _patch_speed(self, q_low: np.ndarray, z: np.ndarray, gn: np.ndarray) -> np.ndarray:
        """Return this rank's part of the patch speed bound (:func:`.bounds.patch_speed_max`)."""
        speed = np.empty(q_low.shape[0])
        bounds.low_order_speed(q_low, self.kappa, speed)
        a = self.active
        return bounds.patch_speed_max(a.compact_cells("cells"), q_low, z, self.g, speed, gn)

    def _finalise(self, q: np.ndarray, q0: np.ndarray, u: np.ndarray, m: np.ndarray) -> bool:
        """Walls: zero normal momentum; films dry; thin layers: damped momentum; bookkeeping.

        ``q`` (new), ``q0`` and ``u`` (start of the step) and the lumped masses ``m`` hold the
        active set's nodes (compact); the others are exactly dry. Films thinner than the dry
        tolerance dry out continuously (:func:`.compact.dry_films`), their volume counted in
        :attr:`dried_volume`. Returns the active set's test of the new state over the ranks
        (:meth:`ActiveSet.deep_inside`: after :func:`.compact.settle` the momenta are zero
        wherever the depth is not positive), sent in this step's last message.
        """
        a = self.active
        sides = a.sides()
        zero_wall_normal(sides, q[:, 1], q[:, 2])
        owned = a.n_owned_nodes
        dried = dry_films(q, self.tol, m, owned)
        # round-off below zero (|h| < 1e-13 h_max) is set to 0; a real negative depth is kept
        # so that the runner stops with a message
        local = float(np.max(np.abs(q[:, 0]))) if q.shape[0] else 0.0
        out = 0.0
        for side in sides:
            if side.kind == "open" and side.nodes.size:
                own = side.nodes < owned
                i = side.nodes[own]
                n = side.normal[own]
                un = np.maximum(u[0, i] * n[:, 0] + u[1, i] * n[:, 1], 0.0)
                out += float(np.sum(side.weight[own] * q0[i, 0] * un))
        inside = self.active_set and a.deep_inside(q[:, 0])
        # one exchange: the largest depth (the same threshold on any partition), the outflow,
        # the dried volume and the active set's test of the next pass
        comm = self.disc.comm
        every = np.empty((comm.size, 4))
        comm.Allgather(np.array([local, out, dried, 1.0 if inside else 0.0]), every)
        hmax = float(every[:, 0].max())
        self.outflow_volume += self._dt * sum(every[:, 1].tolist())  # in rank order
        self.dried_volume += sum(every[:, 2].tolist())
        settle(q, -1e-13 * max(hmax, 1e-300), self.kappa, self.kappa**2)
        return bool(every[:, 3].min() > 0.0)
