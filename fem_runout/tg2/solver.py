"""The TG2-PC solver: state on Q1, transport by TG2-PC + FCT, and its setup from a case."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.config import Case
from fem_runout.errors import CaseError
from fem_runout.initial import depth_below_surface
from fem_runout.mesh import Discretization, build_discretization
from fem_runout.parallel import agree_on_errors
from fem_runout.tg2.transport import Transport


class TG2Solver:
    """Split IMEX-RKC TG2-PC (seed §3.1.2); without friction and rheology, transport only.

    Attributes:
        disc: The discretization.
        transport: The TG2-PC transport operator.
    """

    def __init__(self, disc: Discretization, transport: Transport) -> None:
        self.disc = disc
        self.transport = transport
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
        """Transport CFL limit (the only limit: friction/rheology are implicit or stabilised)."""
        return self.transport.stable_dt()

    def advance(self, dt: float) -> None:
        """One step of size dt."""
        self.transport.step(dt)

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
    """Terrain, depth and momenta at the nodes from the case's expressions."""
    x, y = coords[:, 0], coords[:, 1]
    z = case.terrain.elevation_fn()(x, y)
    depth_fn, surface_fn = case.initial.depth_fn(), case.initial.free_surface_fn()
    if depth_fn is not None:
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


def build_tg2(case: Case, comm: MPI.Comm) -> TG2Solver:
    """Create the TG2-PC solver of a case (collective)."""
    friction, rheology = case.material.friction, case.material.rheology
    if friction.law != "none" or rheology.law != "none":
        raise CaseError(
            f"material: friction law '{friction.law}' / rheology '{rheology.law}' is not "
            "implemented yet for method tg2; allowed now: friction none, rheology none"
        )
    disc = build_discretization(
        comm, case.domain.extent, case.domain.resolved_cells, dict(case.domain.sides)
    )
    init = agree_on_errors(comm, lambda: initial_fields(case, disc.coords))
    num = case.numerics
    thin = num.thin_depth
    if thin is None:
        thin = 1e-6 * comm.allreduce(float(init["h"].max()) if init["h"].size else 0.0, op=MPI.MAX)
    transport = Transport(disc, case.gravity, num.dry_tolerance, thin, num.fct)
    for name in ("z", "h", "hu", "hv"):
        getattr(transport, name).x.array[:] = init[name]
    return TG2Solver(disc, transport)
