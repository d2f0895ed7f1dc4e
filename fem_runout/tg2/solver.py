"""The TG2-PC solver: state on Q1, transport by TG2-PC + FCT, and its setup from a case."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.config import Case
from fem_runout.errors import CaseError
from fem_runout.initial import depth_below_surface
from fem_runout.mesh import Discretization, build_discretization
from fem_runout.parallel import agree_on_errors
from fem_runout.physics.friction import friction_from_spec
from fem_runout.physics.rheology import rheology_from_spec
from fem_runout.physics.slope import slope_geometry
from fem_runout.tg2.diffusion import DiffusionReaction
from fem_runout.tg2.transport import Transport


class TG2Solver:
    """Split IMEX-RKC TG2-PC (seed §3.1.2).

    One step is Strang's ``T(dt/2) D(dt) T(dt/2)``: transport ``T`` by TG2-PC + FCT, and the
    diffusion–reaction ``D`` (Bingham stress by IMEX-RKC, friction implicit per node). Only the
    transport CFL limits ``dt``: each half step uses ``cfl · dt_T``, so :meth:`stable_dt` is
    ``2 dt_T``; the second half is sub-cycled if the state after ``D`` needs it. Without
    friction and rheology ``D`` is None and a step is ``T(dt)`` (nothing else is built).

    Attributes:
        disc: The discretization.
        transport: The TG2-PC transport operator.
        reaction: The diffusion–reaction operator, or None.
    """

    def __init__(
        self,
        disc: Discretization,
        transport: Transport,
        reaction: DiffusionReaction | None = None,
        cfl: float = 0.9,
    ) -> None:
        self.disc = disc
        self.transport = transport
        self.reaction = reaction
        self.cfl = cfl
        self.comm = disc.comm
        self.mesh = disc.mesh
        self.V = disc.V
        self.lumped_mass = disc.lumped_mass
        t = transport
        self.fields = {"h": t.h, "hu": t.hu, "hv": t.hv, "z": t.z}

    @property
    def outflow_volume(self) -> float:
        """Volume that left through open boundaries so far [m³]."""
        return self.transport.outflow_volume

    def stable_dt(self) -> float:
        """Return the transport CFL limit, at most the slope acceleration limit.

        Friction and rheology are implicit or stabilised and do not limit the step.
        """
        dt = self.transport.stable_dt()
        dt = dt if self.reaction is None else 2.0 * dt
        return min(dt, self.transport.acceleration_dt())

    def advance(self, dt: float) -> None:
        """One step of size dt (Strang-split when there is a diffusion–reaction part)."""
        if self.reaction is None:
            self.transport.step(dt)
            return
        self.transport.step(0.5 * dt)
        t = self.transport
        rest = self._unused_capacity(t.state(), dt)
        q = self.reaction.step(t.state()[:, 1:], dt)
        state = t.state()
        state[:, 1:] = q
        for side in self.disc.sides:
            if side.kind == "wall":
                state[side.nodes, 1 if side.normal[0] != 0.0 else 2] = 0.0
        t.set_state(state)
        remaining = 0.5 * dt
        while remaining > 0.0:
            sub = min(remaining, self.cfl * t.stable_dt())
            if sub >= remaining * (1.0 - 1e-12):
                sub = remaining
            t.step(sub)
            remaining -= sub
        if rest is not None:
            state = t.state()
            norm = np.hypot(state[:, 1], state[:, 2])
            keep = np.where(norm > rest, 1.0 - rest / np.where(norm > 0.0, norm, 1.0), 0.0)
            state[:, 1:] *= keep[:, None]
            t.set_state(state)

    def _unused_capacity(self, state: np.ndarray, dt: float) -> np.ndarray | None:
        """Coulomb capacity left after D, ``max(0, dt g μ h - |q|)``, per node (or None).

        Strang's ``T(dt/2) D(dt) T(dt/2)`` ends with a transport half step that gives a layer
        at rest on a slope the impulse ``g S h dt/2``. D has the whole step's Coulomb
        capacity ``dt g μ h`` and used ``|q|`` of it to stop the node; what is left holds
        the second half's impulse: ``q ← q max(0, 1 - rest/|q|)`` after it, the yield test
        of the friction law itself. Giving the second half its own full capacity
        ``dt/2 g μ h`` instead stopped a decelerating sheet up to a quarter step early
        (Coulomb stop test). A projection with no mask: moving nodes have ``rest = 0``.
        """
        friction = self.reaction.friction if self.reaction is not None else None
        if friction is None or friction.mu == 0.0:
            return None
        cap = friction.yield_impulse(state[:, 0], state[:, 1], state[:, 2], dt,
                                     self.reaction.bed(state[:, 1:]))
        return np.maximum(cap - np.hypot(state[:, 1], state[:, 2]), 0.0)

    def snapshot(self) -> tuple[np.ndarray, float]:
        """Copy the state, to restore the last good step."""
        return self.transport.state(), self.transport.outflow_volume

    def restore(self, snap: tuple[np.ndarray, float]) -> None:
        """Restore a :meth:`snapshot`."""
        self.transport.set_state(snap[0])
        self.transport.outflow_volume = snap[1]

    def health(self) -> str | None:
        """Check the state (collective): a message if it has NaN or negative depth, else None."""
        own = slice(0, self.disc.n_owned_nodes)
        q = self.transport.state()[own]
        local = 0
        if not np.isfinite(q).all():
            local = 2
        elif q.shape[0] and q[:, 0].min() < 0.0:
            local = 1
        worst = self.comm.allreduce(local, op=MPI.MAX)
        if worst == 2:
            return "the state has NaN or infinite values"
        if worst == 1:
            hmin = self.comm.allreduce(float(q[:, 0].min()) if q.shape[0] else 0.0, op=MPI.MIN)
            return f"negative depth {hmin:.3e} m"
        return None


def initial_fields(case: Case, coords: np.ndarray) -> dict[str, np.ndarray]:
    """Terrain, depth and momenta at the nodes from the case (every method starts here).

    The elevation comes from ``terrain.dem`` (bilinear on DEM cell centres) or the
    expression; the depth from ``initial.release`` (polygons, raster), ``initial.depth`` or
    ``initial.free_surface``.
    """
    from fem_runout.terrain import elevation_at, initial_depth_at

    x, y = coords[:, 0], coords[:, 1]
    z = elevation_at(case, x, y)
    depth_fn, surface_fn = case.initial.depth_fn(), case.initial.free_surface_fn()
    released = initial_depth_at(case, x, y)
    if released is not None:
        h = released
    elif depth_fn is not None:
        h = np.asarray(depth_fn(x, y), dtype=float)
        scale = max(float(np.abs(h).max()) if h.size else 0.0, 1.0)
        h[(h < 0) & (h > -1e-12 * scale)] = 0.0  # round-off of the node coordinates
        if (h < 0).any():
            raise CaseError(f"initial.depth: must be >= 0 everywhere, min is {h.min():g}")
    else:
        h = depth_below_surface(surface_fn(x, y), z)
    for key, values in (("terrain.elevation", z), ("initial.depth/free_surface", h)):
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise CaseError(f"{key}: the expression gives NaN or inf at {int(bad.sum())} nodes, "
                            f"e.g. x={x[i]:g}, y={y[i]:g}; it must be finite on the whole domain")
    u_fn, v_fn = case.initial.velocity_fns()
    return {"z": z, "h": h, "hu": h * u_fn(x, y), "hv": h * v_fn(x, y)}


def resolved_thin_depth(case: Case, comm: MPI.Comm, h: np.ndarray) -> float:
    """``numerics.thin_depth``, or 1e-6 × the largest initial depth when unset (collective)."""
    if case.numerics.thin_depth is not None:
        return float(case.numerics.thin_depth)
    return 1e-6 * comm.allreduce(float(h.max()) if h.size else 0.0, op=MPI.MAX)


def build_tg2(case: Case, comm: MPI.Comm) -> TG2Solver:
    """Create the TG2-PC solver of a case (collective)."""
    disc = build_discretization(
        comm, case.domain.extent, case.domain.resolved_cells, dict(case.domain.sides)
    )
    init = agree_on_errors(comm, lambda: initial_fields(case, disc.coords))
    num = case.numerics
    thin = resolved_thin_depth(case, comm, init["h"])
    slope = slope_geometry(disc, init["z"], case.gravity, case.model.curvature) \
        if case.slope_form else None
    transport = Transport(disc, case.gravity, num.dry_tolerance, thin, num.fct, slope)
    for name in ("z", "h", "hu", "hv"):
        getattr(transport, name).x.array[:] = init[name]
    friction = friction_from_spec(case.material.friction, case.gravity, num.dry_tolerance)
    rheology = rheology_from_spec(case.material.rheology, case.material.density)
    reaction = None
    if friction is not None or rheology is not None:
        reaction = DiffusionReaction(disc, transport.h, friction, rheology, num.dry_tolerance,
                                     thin, slope)
    return TG2Solver(disc, transport, reaction, case.time.cfl)
