"""The diffusion–reaction operator D of the split scheme (seed §3.1.1–§3.1.2, eqs. 16–20).

Only the momenta change (the mass equation has neither stress nor friction):

    d/dt q_i = F_D(q)_i + F_R(q)_i
    F_D(q)_i = -(1/m_i) ∫ (h/ρ) σ(u) : ∇φ_i dx        (eq. 16, (G, ∇φ_i) with lumped mass)
    F_R(q)_i = r(q_i)                                (eq. 16, nodal friction, eq. 2)

``σ = 2 μ_eff D(u)`` is the regularised Bingham stress of :mod:`fem_runout.physics.rheology`
(eqs. 3–7); ``μ_eff`` is evaluated per cell at the start of the step from the cell's velocity
gradient and frozen during it (lagged viscosity), so ``F_D`` is one compiled UFL form with DG0
coefficients. No boundary flux of G (null ``G·n``, as in the paper).

The depth that multiplies the stress in a cell is the cell's smallest nodal depth ``h_min,K``
(identical to h for a uniform layer, a first-order change where h varies). With the Q1 depth
itself, a thick cell next to a thin front node drags that node's velocity at a rate
``∝ h_K / h_j``, which has no bound: a Bingham dam break with μ = 1e5 Pa s blew up in two steps.
With ``h_min,K``, ``h_min,K ∂u_j/∂q_j <= 2`` and the Gershgorin bound below is rigorous.

With a rheology, ``F_D`` is integrated by the IMEX-RKC of eq. 17 (coefficients eq. 19, stages
eq. 18) with ``σ_J`` from Gershgorin's theorem on the lumped operator; the friction, if any, is
then integrated over the whole step, node by node, by two implicit stages of eq. 20's
semi-smooth Newton (:meth:`FrictionLaw.integrate`, second order). Without
a rheology only the friction update runs. See :meth:`DiffusionReaction.step` for why the
friction is not inside the RKC stages.
"""

from __future__ import annotations

import basix
import basix.ufl
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fem_runout.integrators.rkc import IMEXRKC
from fem_runout.mesh import Discretization
from fem_runout.physics.friction import FrictionLaw
from fem_runout.physics.rheology import Bingham
from fem_runout.physics.slope import BedFrame, SlopeGeometry
from fem_runout.q1 import inverses, jacobians, physical_gradients, q1_basis
from fem_runout.tg2.low_order import velocity_factor


class DiffusionReaction:
    """D(dt): Bingham stress by IMEX-RKC and bed friction implicit per node.

    Args:
        disc: The discretization.
        h: Q1 depth function (read only).
        friction: Friction law or None.
        rheology: Bingham rheology or None.
        dry_tolerance: Dry threshold [m].
        thin_depth: Desingularisation depth κ [m].
        slope: Bed geometry of the slope-consistent form (friction on the bed), or None.
    """

    def __init__(
        self,
        disc: Discretization,
        h: fem.Function,
        friction: FrictionLaw | None,
        rheology: Bingham | None,
        dry_tolerance: float,
        thin_depth: float,
        slope: SlopeGeometry | None = None,
    ) -> None:
        self.disc, self.h, self.slope = disc, h, slope
        self.friction, self.rheology = friction, rheology
        self.tol, self.kappa = dry_tolerance, max(thin_depth, dry_tolerance)
        self.rkc = IMEXRKC()
        self.last_stages = 0
        if rheology is not None:
            self._setup_form()

    def _setup_form(self) -> None:
        d = self.disc
        msh = d.mesh
        Vv = fem.functionspace(msh, basix.ufl.element("P", "quadrilateral", 1, shape=(2,)))
        self.u = fem.Function(Vv)
        P0 = fem.functionspace(msh, ("DG", 0))
        self.nu = fem.Function(P0)  # ν_K = μ_eff / ρ
        self.hmin = fem.Function(P0)  # smallest nodal depth of the cell
        # tested with discontinuous Q1: per cell and node, summed by Discretization.cell_sum
        # (the same bits on any partition)
        Wd = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 1, shape=(2,)))
        w = ufl.TestFunction(Wd)
        eps = ufl.sym(ufl.grad(self.u))
        dx = ufl.dx(metadata={"quadrature_degree": 2})
        self.form = fem.form(-ufl.inner(2.0 * self.hmin * self.nu * eps, ufl.grad(w)) * dx)
        self.vec = fem.assemble_vector(self.form)
        self._dofd = np.asarray(Wd.dofmap.list[: d.n_owned_cells], dtype=np.int64)
        nc = d.cell_nodes.shape[0]
        self._nu_dofs = np.asarray(self.nu.function_space.dofmap.list[:nc, 0])
        xc = d.coords[d.cell_nodes]
        self._grad_c = _center_gradients(xc)
        # Gershgorin: Σ_j |∫_K ∇φ_i·∇φ_j| per cell and node (vector operator: × 2 below)
        self._stiff_rows = _stiffness_row_sums(xc)

    # -- the operator ------------------------------------------------------------------------
    def _velocity(self, q: np.ndarray) -> np.ndarray:
        h = self.h.x.array
        f = np.where(h > self.tol, velocity_factor(h, self.kappa), 0.0)
        return q * f[:, None]

    def diffusion_rate(self, q: np.ndarray) -> np.ndarray:
        """``F_D(q)`` per node, (n, 2), from the compiled form (collective)."""
        d = self.disc
        self.u.x.array[:] = self._velocity(q).reshape(-1)
        self.vec.array[:] = 0.0
        fem.assemble_vector(self.vec.array, self.form)
        per_cell = self.vec.array.reshape(-1, 2)[self._dofd]
        return d.cell_sum(per_cell) / d.lumped_mass[:, None]

    def update_viscosity(self, q: np.ndarray) -> float:
        """Set ν_K = μ_eff/ρ per cell from the state; return σ_J (Gershgorin, collective)."""
        d, rh = self.disc, self.rheology
        cells = d.cell_nodes
        u = self._velocity(q)
        h = self.h.x.array
        hk = h[cells].mean(axis=1)
        uk = u[cells].mean(axis=1)
        grad = np.einsum("cka,ckb->cab", u[cells], self._grad_c)  # grad[c, i, j] = ∂_j u_i
        nu = rh.effective_viscosity(hk, uk[:, 0], uk[:, 1], grad) / rh.density
        nu = np.where(hk > self.tol, nu, 0.0)
        self.nu.x.array[self._nu_dofs] = nu
        self.hmin.x.array[self._nu_dofs] = np.maximum(h[cells].min(axis=1), 0.0)
        no = d.n_owned_cells
        # |∂F_D,i/∂q_j| <= (1/m_i) Σ_K 2 ν_K h_min,K |∂u_j/∂q_j| · 2 |S_ij|, h_min ∂u/∂q <= 2
        rows = d.cell_sum(8.0 * nu[:no, None] * self._stiff_rows[:no])
        own = slice(0, d.n_owned_nodes)
        local = float(np.max(rows[own] / d.lumped_mass[own])) if d.n_owned_nodes else 0.0
        return d.comm.allreduce(local, op=MPI.MAX)

    # -- one step ----------------------------------------------------------------------------
    def step(self, q: np.ndarray, dt: float, nodes: np.ndarray | None = None,
             bed: BedFrame | None = None) -> np.ndarray:
        """Advance the momenta (n, 2) by ``dt``; returns the new momenta.

        The rheology is integrated by the IMEX-RKC of eq. 17 with the friction as its implicit
        reaction only when there is no friction to stop flows; otherwise the RKC handles the
        stress and the friction is integrated afterwards over the whole ``dt`` by two implicit
        stages (:meth:`FrictionLaw.integrate`: second order, exact Coulomb stop). Inside eq. 17
        each stage solves with θ = μ̃₁ dt, which for m >= 4 stages is so small that Coulomb
        friction no longer stops a flow exactly (tests/test_rkc.py); over the full step the
        Coulomb yield test is exact, so a decelerating flow stops and stays stopped.

        Args:
            q: (n, 2) momenta at the local nodes ``nodes`` (all of them with a rheology).
            dt: Time step.
            nodes: Local nodes of the rows of ``q`` (default: all).
            bed: :meth:`bed` of ``q`` if the caller has it (friction only: with a rheology
                the friction's bed is that of the stressed momenta, formed here).
        """
        h = self.h.x.array if nodes is None else self.h.x.array[nodes]
        if self.rheology is not None:
            bed = None
            if nodes is not None and nodes.size != self.h.x.array.size:
                raise ValueError("the rheology's stress needs every node")
            sigma = self.update_viscosity(q)
            q = self.rkc.step(q, dt, sigma, self.diffusion_rate, lambda rhs, th: rhs,
                              lambda w: np.zeros_like(w))
            self.last_stages = self.rkc.last_stages
        if self.friction is not None:
            bed = self.bed(q, nodes) if bed is None else bed
            qx, qy = self.friction.integrate(h, q[:, 0], q[:, 1], dt, bed)
            q = np.stack([qx, qy], axis=1)
        return q

    def bed(self, q: np.ndarray, nodes: np.ndarray | None = None) -> BedFrame | None:
        """Return the bed under the nodes for the friction (None in the seed's form).

        Args:
            q: (n, 2) momenta at the local nodes ``nodes``.
            nodes: Local nodes of the rows of ``q`` (default: all).
        """
        if self.slope is None:
            return None
        h = self.h.x.array if nodes is None else self.h.x.array[nodes]
        slope = self.slope if nodes is None else self._slope_on(nodes)
        f = np.where(h > self.tol, 1.0 / np.where(h > self.tol, h, 1.0), 0.0)
        return slope.frame(q[:, 0] * f, q[:, 1] * f)

    def _slope_on(self, nodes: np.ndarray) -> SlopeGeometry:
        """Return the slope geometry of ``nodes`` (cached for the last node set)."""
        key = self.__dict__.get("_slope_key")
        if key is None or key[0] is not nodes:
            self._slope_key = (nodes, self.slope.take(nodes))
        return self._slope_key[1]


def _center_gradients(xc: np.ndarray) -> np.ndarray:
    """Physical gradients of the four Q1 basis functions at each cell's centre, (n, 4, 2)."""
    _, dphi = q1_basis(np.array([[0.5, 0.5]]))  # (1, 4, 2) reference
    Jinv = inverses(jacobians(xc, dphi))[0][:, 0]
    return np.einsum("kb,cba->cka", dphi[0], Jinv)


def _stiffness_row_sums(xc: np.ndarray) -> np.ndarray:
    """``Σ_j |∫_K ∇φ_i·∇φ_j|`` per cell and node (exact 2×2 Gauss), (n, 4)."""
    pts, wts = basix.make_quadrature(basix.CellType.quadrilateral, 2)
    _, dphi = q1_basis(pts)  # (q, 4, 2)
    Jinv, det = inverses(jacobians(xc, dphi))
    grad = physical_gradients(dphi, Jinv)
    w = wts[None, :] * np.abs(det)
    S = np.einsum("cq,cqia,cqja->cij", w, grad, grad)
    return np.abs(S).sum(axis=2)
