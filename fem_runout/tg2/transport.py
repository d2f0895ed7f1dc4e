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
6. boundary fluxes (open: outflow with the node's own state; wall: zero normal momentum).
"""

from __future__ import annotations

import basix.ufl
import numpy as np
from dolfinx import fem, la
from mpi4py import MPI

from fem_runout.assembly import VectorAssembler
from fem_runout.mesh import Discretization, GhostReducer, facet_measures, zero_wall_normal
from fem_runout.physics.slope import SlopeGeometry
from fem_runout.stepping import acceleration_limit
from fem_runout.tg2 import bounds
from fem_runout.tg2.active import ActiveForms
from fem_runout.tg2.forms import corrector_form, predictor_form
from fem_runout.tg2.limiter import Limiter
from fem_runout.tg2.low_order import (
    cell_means,
    low_order_pass,
    reconstructed_surface,
    velocity,
    velocity_factor,
)

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
    ) -> None:
        self.disc = disc
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
        msh, V = disc.mesh, disc.V
        self.h, self.hu, self.hv, self.z = (fem.Function(V, name=n) for n in ("h", "hu", "hv", "z"))
        self.ux, self.uy = fem.Function(V), fem.Function(V)
        W0 = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 0, shape=(3,)))
        U0 = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 0, shape=(2,)))
        S0 = fem.functionspace(msh, ("DG", 0))
        Wd = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 1, shape=(3,)))
        Sd = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 1))
        self.eta_t, self.Qk = fem.Function(Sd), fem.Function(W0)
        self.uk, self.etak = fem.Function(U0), fem.Function(S0)
        self.dt = fem.Constant(msh, 0.0)
        self.gk = fem.Function(S0)  # per-cell G of the slope form (mean of the nodes')
        g = fem.Constant(msh, self.g) if slope is None else self.gk
        state, vel = (self.h, self.hu, self.hv), (self.ux, self.uy)
        self.pred_form = predictor_form(state, vel, self.eta_t, W0, self.dt, g)
        self.corr_form = corrector_form(
            self.Qk, self.uk, self.etak, Wd, self.dt, g, fem.Constant(msh, self.kappa), self.z,
            facet_measures(disc), disc.spacing,
        )
        self.b_pred = fem.assemble_vector(self.pred_form)
        self.b_corr = [fem.assemble_vector(f) for f in self.corr_form]
        nc = disc.cell_nodes.shape[0]
        self._dof0 = np.asarray(W0.dofmap.list[:nc, 0], dtype=np.int64)
        if not np.array_equal(self._dof0, U0.dofmap.list[:nc, 0]):
            raise RuntimeError("DG0 spaces with different cell numbering")
        self._dofs0 = np.asarray(S0.dofmap.list[:nc, 0], dtype=np.int64)
        self._dofd = _as_slice(np.asarray(Wd.dofmap.list[:nc], dtype=np.int64))
        self._dofsd = _as_slice(np.asarray(Sd.dofmap.list[:nc], dtype=np.int64))
        self._dof0 = _as_slice(self._dof0)
        self._dofs0 = _as_slice(self._dofs0)
        self.reducer = GhostReducer(disc)
        #: the forms on the cells near the flow (same bits as the whole mesh), or None
        forms = [self.pred_form, *self.corr_form]
        self.active = ActiveForms(disc, self.reducer, forms) if active_set else None
        #: the forms' assemblers over the whole mesh (numba calling the FFCx kernels)
        self._assemblers = [VectorAssembler(f) for f in forms] if not active_set else []
        self.limiter = Limiter(disc, self.reducer, self.gn, self.kappa)
        self.outflow_volume = 0.0
        no = disc.n_owned_cells
        self._lo = np.zeros((no, 4, 3))
        self._cap = np.zeros((no, 4))
        self._owned = disc.cell_nodes[:no]
        self._cellC = np.ascontiguousarray(disc.C[:no])
        self._beta = self.limiter.beta_all[:no]  # owned cells come first
        self._means, self._eta_mean = np.empty((nc, 3)), np.empty(nc)
        self._cell_eta = np.empty((nc, 4))
        self._fresh = False  # low-order rates of the current state are in self._lo
        self._active_key, self._active_cache = -1, ()

    # -- state -----------------------------------------------------------------------------
    def state(self) -> np.ndarray:
        """(n_nodes_local, 3) copy of (h, hu, hv)."""
        return np.stack([self.h.x.array, self.hu.x.array, self.hv.x.array], axis=1)

    def set_state(self, q: np.ndarray) -> None:
        """Set (h, hu, hv) from a (n_nodes_local, 3) array (ghosts included)."""
        self.h.x.array[:], self.hu.x.array[:], self.hv.x.array[:] = q[:, 0], q[:, 1], q[:, 2]
        self._fresh = False

    # -- time step ---------------------------------------------------------------------------
    def stable_dt(self) -> float:
        """Largest dt for which the low-order update keeps h >= 0 (CFL number 1).

        ``dt = min_i m_i / (Σ_j (d_ij + |β_ij·u_i|) + Σ_open w_i max(u_i·n, 0))``, with the
        eigenvalues ``|u·n| + sqrt(g h)`` of the full system in ``d_ij``. The low-order rates of
        the same pass are kept for the next :meth:`step`.
        """
        d = self.disc
        self._low_order_pass()
        cap = d.cell_sum(self._cap)
        ux, uy = self.ux.x.array, self.uy.x.array
        for side in d.sides:
            if side.kind == "open":
                un = ux[side.nodes] * side.normal[0] + uy[side.nodes] * side.normal[1]
                cap[side.nodes] += side.weight * np.maximum(un, 0.0)
        own = slice(0, d.n_owned_nodes)
        c, m = cap[own], d.lumped_mass[own]
        ratio = m[c > 0.0] / c[c > 0.0]
        local = float(ratio.min()) if ratio.size else np.inf
        return d.comm.allreduce(local, op=MPI.MIN)

    def acceleration_dt(self) -> float:
        """Return ``sqrt(Δx / (g S_max))``, ``S_max`` the steepest bed slope at a wet node.

        A layer starting at rest on the slope moves at most half a cell in one step. The wave
        speed alone (``sqrt(g h)``) allowed a 3 s step to a 1e-4 m film on a slope and a 6 s
        one to a layer at rest on 40° (the ``Z`` slope is computed once, patch maximum of the
        cell-mean gradients).
        """
        if self._slope is None:
            self._slope = bounds.node_slopes(self.disc, self.z.x.array, self.reducer)
        own = slice(0, self.disc.n_owned_nodes)
        wet = np.clip(self.h.x.array[own] / self.wet_depth, 0.0, 1.0)  # continuous wet weight
        s = self._slope[own] * wet
        local = float(s.max()) if s.size else 0.0
        top = self.disc.comm.allreduce(local, op=MPI.MAX)
        return acceleration_limit(min(self.disc.spacing), self.g, top)

    def _low_order_pass(self) -> None:
        """Velocity, low-order rates A_L (self._lo) and capacities (self._cap) of the state."""
        h, hu, hv, z = self.h.x.array, self.hu.x.array, self.hv.x.array, self.z.x.array
        velocity(h, hu, hv, self.kappa, self.ux.x.array, self.uy.x.array)
        if self.slope is not None:
            self.gn[:] = self.slope.pressure_gravity(self.ux.x.array, self.uy.x.array)
        self._cap[:] = 0.0
        if self.active is None:
            low_order_pass(self._owned, self._beta, self._cellC, h, hu, hv, z, self.ux.x.array,
                           self.uy.x.array, self.gn, self.kappa, self._lo, self._cap)
        else:  # dry cells give exact zeros: visit the active ones only (tg2/active.py)
            self.active.update(self.state())
            cells, beta, cc, lo, cap = self._active_arrays()
            cap[:] = 0.0
            low_order_pass(cells, beta, cc, h, hu, hv, z, self.ux.x.array, self.uy.x.array,
                           self.gn, self.kappa, lo, cap)
            self._lo[:] = 0.0
            self._lo[self.active.owned], self._cap[self.active.owned] = lo, cap
        self._fresh = True

    def _active_arrays(self) -> tuple[np.ndarray, ...]:
        """Return the active owned cells' nodes, pair and ``C`` coefficients and buffers.

        Cached until the active set is rebuilt.
        """
        if self._active_key != self.active.rebuilds:
            idx = self.active.owned
            self._active_cache = (np.ascontiguousarray(self._owned[idx]),
                                  np.ascontiguousarray(self._beta[idx]),
                                  np.ascontiguousarray(self._cellC[idx]),
                                  np.empty((idx.size, 4, 3)), np.empty((idx.size, 4)))
            self._active_key = self.active.rebuilds
        return self._active_cache

    def step(self, dt: float) -> None:
        """Advance (h, hu, hv) by ``dt``."""
        d = self.disc
        self.dt.value = dt
        h, hu, hv, z = self.h.x.array, self.hu.x.array, self.hv.x.array, self.z.x.array
        if not self._fresh:
            self._low_order_pass()
        eta_t = self.eta_t.x.array.reshape(-1)
        cell_eta = self._cell_eta
        reconstructed_surface(d.cell_nodes, h, z, self.kappa, cell_eta)
        if isinstance(self._dofsd, slice):
            eta_t.reshape(-1, 4)[self._dofsd] = cell_eta
        else:
            eta_t[self._dofsd] = cell_eta
        if self.slope is not None:
            self.gk.x.array[self._dofs0] = self.gn[d.cell_nodes].mean(axis=1)
        q0 = self.state()
        # the low-order pass of this state (here or in stable_dt) updated the active set
        forms = self._assemblers if self.active is None else self.active.forms
        high = self._high_order(cell_eta, forms[0], forms[1:])
        low_rate = self._low_order_rates(h, hu, hv)
        q_low = q0 + dt * low_rate
        aec = high - dt * self._lo
        if self.fct_enabled:
            corr = self.limiter.correction(q0, q_low, aec, self.z.x.array,
                                           np.stack([self.ux.x.array, self.uy.x.array]))
        else:
            corr = d.cell_sum(aec)
        q_new = q_low + corr / d.lumped_mass[:, None]
        self._bound_speed(q_low, q_new)
        self._finalise(q_new)
        self.set_state(q_new)

    # -- pieces ------------------------------------------------------------------------------
    def _high_order(self, cell_eta: np.ndarray, pred_form: VectorAssembler,
                    corr_forms: list[VectorAssembler]) -> np.ndarray:
        """Predictor (DG0) then corrector element contributions A_H (owned cells, × dt)."""
        d = self.disc
        b = self.b_pred
        b.array[:] = 0.0
        pred_form.assemble(b.array)
        Qk = self.Qk.x.array.reshape(-1, 3)
        Qk[self._dof0] = b.array.reshape(-1, 3)[self._dof0] / d.cell_area[:, None]
        self.Qk.x.scatter_forward()
        delta = Qk[self._dof0].copy()  # a view when _dof0 is a slice
        means, eta_mean = self._means, self._eta_mean
        cell_means(d.cell_nodes, self.h.x.array, self.hu.x.array, self.hv.x.array, cell_eta,
                   means, eta_mean)
        vals = means + delta
        Qk[self._dof0] = vals
        hk = vals[:, 0]
        self.etak.x.array[self._dofs0] = eta_mean + delta[:, 0]
        factor = velocity_factor(hk, self.kappa)
        self.uk.x.array.reshape(-1, 2)[self._dof0] = vals[:, 1:] * factor[:, None]
        for vec, form in zip(self.b_corr, corr_forms, strict=True):
            vec.array[:] = 0.0
            form.assemble(vec.array)
            vec.scatter_reverse(la.InsertMode.add)  # one facet term per dof: exact
        b = self.b_corr[0]
        b.array[:] += self.b_corr[1].array  # cell + vertical facets, then horizontal facets
        if isinstance(self._dofd, slice):
            return b.array.reshape(-1, 4, 3)[: d.n_owned_cells]
        return b.array.reshape(-1, 3)[self._dofd[: d.n_owned_cells]]

    def _low_order_rates(self, h, hu, hv) -> np.ndarray:
        """Nodal low-order rate (Σ_K A_L[K, i] + boundary flux) / m_i from self._lo."""
        d = self.disc
        acc = d.cell_sum(self._lo)
        acc += self._boundary_flux(h, hu, hv)
        return acc / d.lumped_mass[:, None]

    def _boundary_flux(self, h, hu, hv) -> np.ndarray:
        """Open sides: outflow ``-w_i F(U_i)·n⁺``; nothing enters; walls take nothing through.

        Material leaves through an open side with the node's own state (non-reflecting for
        outgoing flow). Nothing enters: with the zero-gradient state an inflowing node gains
        mass and momentum in proportion to ``q |u·n|``, a feedback that blew up at the open
        sides of the inclined dam break, and a run-out domain has nothing outside to bring in.
        """
        flux = np.zeros((h.shape[0], 3))
        ux, uy = self.ux.x.array, self.uy.x.array
        for side in self.disc.sides:
            if side.kind != "open":
                continue
            i = side.nodes
            un = np.maximum(ux[i] * side.normal[0] + uy[i] * side.normal[1], 0.0)
            w = side.weight
            flux[i, 0] -= w * h[i] * un
            flux[i, 1] -= w * hu[i] * un
            flux[i, 2] -= w * hv[i] * un
        return flux

    def _bound_speed(self, q_low: np.ndarray, q: np.ndarray) -> None:
        """Scale back momenta above the patch speed bound (:func:`.bounds.bound_speed`)."""
        ux, uy = np.empty(q.shape[0]), np.empty(q.shape[0])
        velocity(np.ascontiguousarray(q_low[:, 0]), np.ascontiguousarray(q_low[:, 1]),
                 np.ascontiguousarray(q_low[:, 2]), self.kappa, ux, uy)
        bounds.bound_speed(self.disc.cell_nodes, self.reducer, q_low, q, self.z.x.array, self.g,
                           np.hypot(ux, uy), self.gn)

    def _finalise(self, q: np.ndarray) -> None:
        """Walls: zero normal momentum; thin layers: damped momentum; outflow bookkeeping."""
        d = self.disc
        zero_wall_normal(d.sides, q[:, 1], q[:, 2])
        # round-off below zero (|h| < 1e-13 h_max) is set to 0; a real negative depth is kept
        # so that the runner stops with a message
        local = float(np.max(np.abs(q[:, 0]))) if q.shape[0] else 0.0
        hmax = d.comm.allreduce(local, op=MPI.MAX)  # global: the same threshold on any partition
        tiny = (q[:, 0] < 0.0) & (q[:, 0] > -1e-13 * max(hmax, 1e-300))
        q[tiny, 0] = 0.0
        # thin layers: momenta damped by 2h²/(h² + κ²) below κ (1 at κ, 0 at h = 0: continuous)
        thin = q[:, 0] < self.kappa
        ht = np.maximum(q[thin, 0], 0.0)
        q[thin, 1:] *= (2.0 * ht * ht / (ht * ht + self.kappa**2))[:, None]
        out = 0.0
        h, ux, uy = self.h.x.array, self.ux.x.array, self.uy.x.array
        for side in d.sides:
            if side.kind == "open":
                own = side.nodes < d.n_owned_nodes
                i = side.nodes[own]
                un = np.maximum(ux[i] * side.normal[0] + uy[i] * side.normal[1], 0.0)
                out += float(np.sum(side.weight[own] * h[i] * un))
        self.outflow_volume += float(self.dt.value) * d.comm.allreduce(out)


def _as_slice(dofs: np.ndarray) -> np.ndarray | slice:
    """Return a slice when consecutive cells have consecutive dofs (a view, no copy).

    For an (n, k) dof list the slice indexes an array reshaped to (-1, k); for (n,) a flat one.
    """
    flat = dofs.reshape(-1)
    if np.array_equal(flat, np.arange(flat.size)):
        return slice(0, dofs.shape[0])
    return dofs
