"""The DAMPM solver (seed §3.2): material points on fem_runout's Q1 space, USL, MPI-parallel.

One step of size ``Δt`` (the grid sums of the current particles are cached from the end of the
previous step):

1. nodal mass, momentum and force (P2G, seed eqs. 33-34, lumped ``M_i``), nodal acceleration
   and velocity (eqs. 35-37) ``v_i^* = (p_i + Δt f_i)/M_i``;
2. bed friction (eq. 2) per node with the nodal depth ``h_i = M_i/(ρ Σ_p A_p N_i)``,
   Strang-split around the forces: half of ``Δt f_i``, the friction over ``Δt`` (two
   implicit stages, the same exact Coulomb yield test as TG2's D step), the other half
   (:func:`mpm.nodal.friction_step`); zero normal velocity on walls;
3. G2P (eq. 38) ``v_p = Σ_i v_i N_i(x_p)``; the velocity gradient ``L_p`` of eq. 40 is taken
   from the nodal velocity re-mapped from the updated particles (MUSL, Sulsky et al. 1995):
   eq. 37's ``(p_i + Δt f_i)/M_i`` is unbounded at nodes with little mass, and its gradient
   collapsed particle columns (``1 + tr Δε <= 0``) in viscous and wall-reflection runs;
4. strain increment ``Δε_p = Δt sym(L_p)`` (eq. 40), depth
   ``h_p = min(h_p, κ h̄_p) / (1 + tr Δε_p)`` (eq. 42, capped at κ times the grid depth
   ``h̄_p``: :func:`mpm.constitutive.update_depth_and_stress`), stress ``σ_p = 2 μ_eff D_p``
   (eqs. 3, 41; USL: updated last);
   positions ``x_p += Δt v_p^{k+1}`` (eq. 39 with the updated velocity, cell-local);
5. particles leaving through open sides are removed (their volume counted as outflow), the
   others are rebalanced over the ranks every :data:`mpm.migrate.REBALANCE_EVERY` steps
   (strips of cells, :mod:`mpm.migrate`); P2G of the new state; projection of ``h, hu, hv``
   onto Q1 for the outputs (:mod:`mpm.projection`).

Forces (eq. 34): body ``-m_p g ∇Z(x_p) N_i`` and effective stress ``-V_p σ^∇_p ∇N_i`` with
``σ^∇ = σ - ½ ρ g h I`` (eq. 26). With a still-water depth ``H`` (a flat initial free surface)
the well-balanced form of eq. 46 is used: pressure ``½ ρ g (h² - H²)`` and body
``-ρ g A_p (h_p - H_p) ∇Z``, both exactly zero for a lake at rest.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.exact_sum import fold_extractors
from fem_runout.health import reduce_flag, state_flag
from fem_runout.mesh import Discretization
from fem_runout.physics.friction import FrictionLaw
from fem_runout.physics.rheology import Bingham
from fem_runout.physics.slope import SlopeGeometry
from mpm.collective import CollectiveSteps
from mpm.constitutive import update_depth_and_stress
from mpm.exchange import FoldExchange
from mpm.fields import FieldWriter
from mpm.grid import ParticleGrid
from mpm.mesh_grid import MeshParticleGrid
from mpm.migrate import REBALANCE_EVERY, balanced_destinations, migrate
from mpm.nodal import (
    GridSums,
    NodalGrid,
    NodeBuffers,
    friction_step,
    no_faster_than,
    open_side_push,
    zero_wall_velocity,
)
from mpm.particles import Particles
from mpm.quad_split import QuadSplitter
from mpm.split import DomainSplitter, PendingIds
from mpm.step_limits import COURANT, limits_from, local_limits

__all__ = ["COURANT", "DEPTH_CAP", "MPMSolver"]

#: A particle column is at most this many times the depth the particle volumes make on the
#: grid where it is (:meth:`MPMSolver.update_depth_and_stress`).
DEPTH_CAP = 3.0

class MPMSolver(CollectiveSteps):
    """Depth-averaged MPM with the solver interface of :mod:`fem_runout.solver_api`.

    Args:
        disc: The shared discretization.
        grid: Particle location on it.
        particles: The particles of this rank.
        z: Nodal elevation (local, with ghosts).
        density: ``ρ`` [kg/m³].
        gravity: ``g`` [m/s²].
        friction: Bed friction law or None.
        rheology: Bingham rheology or None.
        still_depth: Nodal still-water depth ``H`` (well-balanced eq. 46) or None.
        flip: FLIP fraction of the particle velocity update (0: PIC, eq. 38 of the seed).
        per_direction: Particles per cell and direction at the start (the split limit).
        thin_depth: Particles thinner than this are not split [m] (:mod:`mpm.split`).
        slope: Bed geometry of the slope-consistent form (local nodes), or None for the
            seed's form: ``g`` of the body force and the pressure becomes
            ``G_p = cos²θ max(g + u_p·H·u_p, 0)`` at each particle, the friction acts on the
            bed (:mod:`fem_runout.physics.slope`).
        apic: Use the affine transfer (APIC) instead of the FLIP/PIC blend: the particles
            take the PIC velocity and the grid velocity's gradient ``C_p`` and give the grid
            ``m_p S_ip (v_p + C_p (x_i - x̄_p))`` (docs/dampm.md, "Velocity transfer").
        depth_cap: ``κ`` of :meth:`update_depth_and_stress` (None: the seed's eq. 42 alone).
    """

    def __init__(self, disc: Discretization, grid: ParticleGrid | MeshParticleGrid,
                 particles: Particles,
                 z: np.ndarray, density: float, gravity: float,
                 friction: FrictionLaw | None = None, rheology: Bingham | None = None,
                 still_depth: np.ndarray | None = None, flip: float = 0.0,
                 per_direction: int = 2, thin_depth: float = 0.0,
                 slope: SlopeGeometry | None = None, apic: bool = False,
                 depth_cap: float | None = DEPTH_CAP) -> None:
        self.disc, self.grid = disc, grid
        # C_p only with APIC, the corners only on a gmsh mesh (Particles.with_fields)
        self.particles = particles.with_fields(bool(apic), not grid.structured)
        self.comm, self.mesh, self.V = disc.comm, disc.mesh, disc.V
        self.rho, self.g = float(density), float(gravity)
        self.friction, self.rheology = friction, rheology
        self.flip, self.apic = (0.0 if apic else float(flip)), bool(apic)
        self.depth_cap = depth_cap
        self.z = np.asarray(z, dtype=float)
        self.k = grid.transfers  # the kernels of the grid's basis
        self.nodal = NodalGrid(disc, grid)
        self.writer = FieldWriter(disc.V, self.nodal, self.z)
        self.fields = self.writer.fields
        self.z_g = self.nodal.to_global(self.z)
        self.still_g = None if still_depth is None else self.nodal.to_global(still_depth)
        self.slope_g = None if slope is None else self.nodal.geometry_to_global(slope)
        self._hess = np.zeros((0, 3)) if self.slope_g is None else self.slope_g.hess
        self._still = np.zeros(0) if self.still_g is None else self.still_g
        self.projector = grid.projector()
        self.exchange = FoldExchange(self.comm)
        self.buffers = NodeBuffers(self.nodal.n_nodes)
        self.lumped_mass = self.nodal.to_local(self.projector.lumped_mass)
        n_ids = self.comm.allreduce(int(particles.id.max(initial=-1)), op=MPI.MAX) + 1
        splitter = DomainSplitter if grid.structured else QuadSplitter
        self.splitter = splitter(grid, per_direction, n_ids, thin_depth)
        self.outflow_volume = 0.0
        self._left = 0.0  # outflow of this rank not yet summed over the ranks
        self.sent = 0
        self._snap_store: dict[str, np.ndarray] | None = None  # reused by :meth:`snapshot`
        self._since_balance = 0  # steps since the particles were balanced over the ranks
        self._problem: str | None = None
        self._pending: PendingIds | None = None  # split children whose ids wait for a message
        self.walls = [s for s in self.nodal.sides if s.kind == "wall"]
        self.open_sides = [s for s in self.nodal.sides if s.kind == "open"]
        self._refresh()

    # -- solver interface ------------------------------------------------------------------
    @property
    def _box_args(self) -> np.ndarray:
        """The P2G box as the kernels take it: ``(row, column, rows, columns)``."""
        box = self._box
        return np.array([box.j0, box.i0, box.h, box.w], dtype=np.int64)

    @property
    def n_particles(self) -> int:
        """Global number of particles."""
        return int(self.comm.allreduce(len(self.particles), op=MPI.SUM))

    def particle_volume(self) -> float:
        """Global particle volume ``Σ_p V_p`` [m³] (collective)."""
        return float(self.comm.allreduce(float(self.particles.volume.sum()), op=MPI.SUM))

    def stable_dt(self) -> float:
        """``COURANT Δx / max(|v_p| + sqrt(g h_p))``, the slope and viscous limits."""
        return self._step_limits()[0]

    def particle_elevation(self) -> np.ndarray:
        """Terrain elevation at this rank's particles (Q1 interpolation; local, no MPI)."""
        return self.k.interpolate(self._basis.arrays, self.z_g)

    def _step_limits(self) -> tuple[float, float]:
        """``(stable step, transport step)`` of the current state (collective, no side effect).

        The ratio sets the PIC share of :meth:`advance`: it damps per unit time as at the
        transport step, whatever the viscous limit (docs/dampm.md, "FLIP/PIC blend").
        Computed once per state (:meth:`_refresh` starts a new one).
        """
        if self._limits is None:
            self._limits = self._compute_step_limits()
        return self._limits

    def _compute_step_limits(self) -> tuple[float, float]:
        """Compute the limits of :meth:`_step_limits` (collective: one max reduction)."""
        both = self._local_limits()
        self.comm.Allreduce(MPI.IN_PLACE, both, op=MPI.MAX)
        return self._limits_from(both)

    def _local_limits(self) -> np.ndarray:
        """Return this rank's :func:`mpm.step_limits.local_limits` (local)."""
        return local_limits(self.particles, self.grid, self._speed, self._slope, self._gp,
                            self.g, self._basis)

    def _limits_from(self, both: np.ndarray) -> tuple[float, float]:
        """:meth:`_step_limits` from the ranks' maxima of :meth:`_local_limits`."""
        mu = self.rheology.viscosity if self.rheology is not None else 0.0
        return limits_from(both, self.grid, self.g, self.rho, mu)

    def _pic_scale(self) -> float:
        """``Δt_stable / Δt_transport`` (collective), see :meth:`_step_limits`."""
        dt, transport = self._step_limits()
        return dt / transport if np.isfinite(transport) and transport > 0 else 1.0

    def advance(self, dt: float) -> None:
        """One USL step (see the module docstring)."""
        scale = self._pic_scale() if self.flip > 0.0 else 1.0
        vx, vy = self._nodal_velocity(dt)
        p, b = self.particles, self._basis
        sums = self._own
        mass = sums.g[:, 0]
        keep = 0.0  # PIC (seed eq. 38)
        if self.flip > 0.0:  # FLIP: the particles keep their velocity plus the nodal change
            stopped = self._put("stopped", sums, (vx[sums.act] == 0.0) & (vy[sums.act] == 0.0))
            keep = 1.0 - (1.0 - self.flip) * scale  # PIC next to nodes friction stopped
            old_x = self._put("old_x", sums, sums.g[:, 1] / mass)
            old_y = self._put("old_y", sums, sums.g[:, 2] / mass)
        else:
            stopped = old_x = old_y = self._put("zero", sums, 0.0)
        p.u, p.v = self.k.g2p_flip(b.arrays, vx, vy, old_x, old_y, stopped, p.u, p.v, keep)
        if self.apic:
            c = self.k.g2p_gradient(b.arrays, vx, vy)
            p.cxx, p.cxy, p.cyx, p.cyy = (np.ascontiguousarray(c[:, a, k])
                                          for a in range(2) for k in range(2))
        grad = self.k.g2p_gradient(b.arrays, *self._strain_velocity(vx, vy))
        self.update_depth_and_stress(dt, grad, self._grid_depth())
        self.splitter.stretch(p, dt, grad)
        self._move(dt * p.u, dt * p.v)
        self.particles, self._pending = self.splitter.split_pair(self.particles)
        self._since_balance += 1
        self.sent = 0
        if self._since_balance >= REBALANCE_EVERY:  # any rank may hold any particle
            self._since_balance = 0
            self._settle_split()  # the ids travel with the particles
            self.particles, self.sent = migrate(
                self.grid, self.particles, balanced_destinations(self.grid, self.particles))
        self._refresh()

    def snapshot(self) -> tuple[Particles, float]:
        """Copy of the state, valid until the next snapshot (its memory is reused)."""
        snap, self._snap_store = self.particles.copy_into(self._snap_store)
        return snap, self.outflow_volume

    def restore(self, snap: tuple[Particles, float]) -> None:
        """Restore a :meth:`snapshot`."""
        self.particles, self.outflow_volume = snap[0].copy(), snap[1]
        self._left = 0.0
        self._problem = None
        self._pending = None
        self._refresh()

    def flow_dofs(self) -> np.ndarray:
        """Owned dofs of the projection's window (the fields are zero outside it)."""
        return self._flow

    def health(self, also_max: np.ndarray | None = None) -> str | None:
        """Return a message if a particle has NaN or a collapsed column, else None.

        ``also_max`` is maximised over the ranks in the same reduction (in place), and so
        are the next step's limits (:meth:`_step_limits` of this state): one reduction for
        the step's check and the next step's size.
        """
        local = self._problem or ""
        p = self.particles
        if not local and state_flag(p.h, p.u, p.v, len(p)) == 2:  # one pass, no copies
            local = "the particle state has NaN or infinite values"
        with np.errstate(all="ignore"):  # (of a bad state: not used)
            limits = self._local_limits()
        if not reduce_flag(self.comm, 1 if local else 0, limits, also_max):  # the usual step
            self._limits = self._limits_from(limits)
            return None
        return next(m for m in self.comm.allgather(local) if m)

    # -- steps -----------------------------------------------------------------------------
    def _nodal_velocity(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Nodal velocity at t + dt (eqs. 35-37), with implicit friction and walls.

        Computed on the nodes with mass that this rank's particles reach (:attr:`_own`, a
        :class:`mpm.nodal.GridSums`; node by node, so the same bits on any split); zero
        elsewhere.
        """
        sums = self._own
        g = sums.g
        mass = g[:, 0]
        fx, fy = self._open_side_pressure(g[:, 3], g[:, 4])
        if self.friction is None:
            vx, vy = (g[:, 1] + dt * fx) / mass, (g[:, 2] + dt * fy) / mass
            self._zero_walls(vx, vy)
            return self._put("vx", sums, vx), self._put("vy", sums, vy)
        ax, ay = 0.5 * dt * fx / mass, 0.5 * dt * fy / mass
        vx, vy = g[:, 1] / mass + ax, g[:, 2] / mass + ay
        self._zero_walls(vx, vy)  # the wall reaction first: friction acts along it
        area = g[:, 5]  # > 0 wherever mass is, unless the particles' areas underflow
        h = np.where(area > 0.0, mass / (self.rho * np.where(area > 0.0, area, 1.0)), 0.0)
        bed = None if self.slope_g is None else self.slope_g.take(sums.act).frame(vx, vy)
        vx, vy = friction_step(self.friction, h, vx, vy, ax, ay, dt, bed, self._zero_walls)
        return self._put("vx", sums, vx), self._put("vy", sums, vy)

    def _zero_walls(self, vx: np.ndarray, vy: np.ndarray) -> None:
        """Zero the wall-normal velocity at the walls' nodes with mass (in place)."""
        zero_wall_velocity(self.walls, self._own, vx, vy)

    def _open_side_pressure(self, fx: np.ndarray, fy: np.ndarray) -> tuple[np.ndarray, ...]:
        """Add the pressure of the fluid beyond open sides (:func:`mpm.nodal.open_side_push`)."""
        return open_side_push(self.open_sides, self._own, self._h, self.still_g,
                              0.5 * self.rho * self.g, fx, fy)

    def _strain_velocity(self, vx: np.ndarray, vy: np.ndarray) -> tuple[np.ndarray, ...]:
        """Nodal velocity of the strain (eq. 40): MUSL ``Σ_p m_p v_p^{k+1} N_i / M_i``.

        A mass-weighted average of the updated particle velocities, so it stays bounded at
        nodes that carry little mass (where ``(p_i + Δt f_i)/M_i`` of eq. 37 does not). With
        friction it is no faster than the nodes' friction-updated ``v_i``
        (:func:`mpm.nodal.no_faster_than`): the average reaches held nodes from the moving
        particles beside them, and a column at rest in a deposit kept thickening (an avaKot
        remnant grew from 4 cm to 7e4 m and collapsed the step).
        """
        p, sums = self.particles, self._own
        mass = self.rho * p.volume
        su, sv = p.transfer_speeds(self.grid.dx, self.grid.dy, self.apic)
        top = np.array([_amax(mass * su), _amax(mass * sv)])
        mom = self._momentum_sums(mass, top)[sums.index]
        mass = sums.g[:, 0]
        mx, my = mom[:, 0] / mass, mom[:, 1] / mass
        self._zero_walls(mx, my)
        if self.friction is not None:
            mx, my = no_faster_than(mx, my, vx[sums.act], vy[sums.act])
        return self._put("mvx", sums, mx), self._put("mvy", sums, my)

    def _grid_depth(self) -> np.ndarray | None:
        """Return the depth the particle volumes make on the grid at the particles, or None.

        ``h̄_p = Σ_i S_ip h^L_i`` with the lumped projection ``h^L_i = Σ_q V_q S_iq / M_i``
        (non-negative and continuous in the data); None without a depth cap.
        """
        if self.depth_cap is None:
            return None
        sums = self._own
        lumped = self._put("lumped", sums, sums.g[:, 6] / self.projector.lumped_mass[sums.act])
        return self.k.interpolate(self._basis.arrays, lumped)

    def update_depth_and_stress(self, dt: float, grad: np.ndarray,
                                grid_depth: np.ndarray | None = None) -> None:
        """Update the particle depth (eq. 42) and stress (eqs. 40-41) from the velocity gradient.

        :func:`mpm.constitutive.update_depth_and_stress` with this solver's rheology and
        ``depth_cap``; a collapsed column stops the run at the next health check.
        """
        problem = update_depth_and_stress(self.particles, dt, grad, self.rheology,
                                          grid_depth, self.depth_cap)
        if problem is not None:
            self._problem = problem

    def _move(self, dx: np.ndarray, dy: np.ndarray) -> None:
        """Move the particles (eq. 39 with v^{k+1}); open sides remove, walls stop them."""
        p, grid = self.particles, self.grid
        if not (np.isfinite(dx).all() and np.isfinite(dy).all()):
            self._problem = "the particle velocity has NaN or infinite values"
            return
        p.cell, p.xi, p.eta, out, swap = grid.displace(p.cell, p.xi, p.eta, dx, dy)
        if swap is not None and swap.any():  # the new cells' axes are the old ones swapped
            p.lx[swap], p.ly[swap] = p.ly[swap], p.lx[swap]
        self._left += float(p.volume[out].sum())  # summed over the ranks in _refresh
        if out.any():
            self.particles = p.select(~out)

    def _refresh(self) -> None:
        """Basis at the particles, P2G of the current state, Q1 projection for the outputs."""
        self._limits: tuple[float, float] | None = None
        mass, area, forces, local, bounds, union = self._particle_terms()
        p, b = self.particles, self._basis
        self._musl_bound = 2.0 * bounds[1:3]  # m |v| may grow within the step (_momentum_sums)
        ext = fold_extractors(bounds, self.splitter.next_id)
        box = self._box = self.nodal.box(local[11:])
        folds = self.k.p2g(b.arrays, mass, p.u, p.v, p.affine(), *forces, area, p.volume,
                    self._box_args, ext)
        left = np.array([self._left])  # the volume _move removed, in the folds' message
        totals = self.exchange.start(folds, box, self.nodal.box(union), left)
        self.outflow_volume += float(left[0])
        self._left = 0.0
        self._sums = sums = self.nodal.with_mass(self.exchange.nodes, totals)
        # the nodes this rank's particles reach lie in its box's rows and columns
        self._own = sums.restrict(box.j0 * box.nx1 + box.i0,
                                  (box.j0 + box.h - 1) * box.nx1 + box.i0 + box.w)
        index, values = self.projector.project_nodes(sums.act, sums.g[:, 6])
        # the outputs read only the nonzero nodes: the blend's nodes reach a cell beyond the
        # flow's, where some values are exactly zero (same fields, same bits)
        index, values = _nonzero(index, values)
        self._h = h = self.buffers.put("h", index, values)
        self.writer.write("h", index, values)
        self._flow = self.writer.owned_dofs(index)
        for name, col in (("hu", 1), ("hv", 2)):  # h times the mass-averaged particle velocity
            self.writer.write(name, sums.act, h[sums.act] * sums.g[:, col] / sums.g[:, 0])

    def _put(self, name: str, sums: GridSums, values: np.ndarray | float) -> np.ndarray:
        """Global node array ``name`` with ``values`` at ``sums.act``, zero elsewhere."""
        return self.buffers.put(name, sums.act, values)


def _amax(values: np.ndarray) -> float:
    """Largest absolute value (0 for none)."""
    return float(np.max(np.abs(values), initial=0.0))


def _nonzero(index: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the entries of ``(index, values)`` whose value is not zero."""
    keep = np.flatnonzero(values)
    return index[keep], values[keep]
