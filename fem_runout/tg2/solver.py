"""The TG2-PC solver: state on Q1, transport by TG2-PC + FCT, and its setup from a case."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.config import Case
from fem_runout.health import reduce_flag, state_flag
from fem_runout.mesh import Discretization, zero_wall_normal
from fem_runout.physics.friction.base import spend_capacity
from fem_runout.physics.slope import BedFrame
from fem_runout.problem import build_problem
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
        self._limits: tuple[float, float] | None = None  # stable_dt of the state, if known
        self._snap: np.ndarray | None = None  # the snapshot's buffer, reused

    @property
    def n_particles(self) -> None:
        """None: TG2-PC carries no particles."""
        return None

    @property
    def outflow_volume(self) -> float:
        """Volume that left through open boundaries so far [m³]."""
        return self.transport.outflow_volume

    @property
    def dried_volume(self) -> float:
        """Volume of the films that dried out so far [m³] (:func:`.compact.dry_films`)."""
        return self.transport.dried_volume

    def stable_dt(self) -> float:
        """Return the transport CFL limit, at most the slope acceleration limit.

        Friction and rheology are implicit or stabilised and do not limit the step.
        """
        if self._limits is not None:  # reduced with the last health check, same state
            (dt, slope_dt), self._limits = self._limits, None
        else:
            dt, slope_dt = self.transport.stable_dt(with_slope=True)
        dt = dt if self.reaction is None else 2.0 * dt
        return min(dt, slope_dt)

    def advance(self, dt: float) -> None:
        """One step of size dt (Strang-split when there is a diffusion–reaction part).

        With friction only, ``D`` is node-wise: it works on the transport's active nodes
        (the flow is exactly zero elsewhere); the rheology's stress couples the nodes and
        works on all of them.
        """
        self._limits = None
        if self.reaction is None:
            self.transport.step(dt)
            return
        t = self.transport
        t.step(0.5 * dt)
        nodes = t.active.nodes if self.reaction.rheology is None else None
        state = self._state(nodes)
        # the friction's bed under the state (one for the capacity and the step: the same q)
        once = self.reaction.rheology is None and self.reaction.friction is not None
        bed = self.reaction.bed(state[:, 1:], nodes) if once else None
        rest = self._unused_capacity(state, dt, nodes, bed)
        state[:, 1:] = self.reaction.step(state[:, 1:], dt, nodes, bed)
        sides = self.disc.sides if nodes is None else t.active.sides()
        zero_wall_normal(sides, state[:, 1], state[:, 2])
        self._set_state(nodes, state)
        remaining = 0.5 * dt
        while remaining > 0.0:
            sub = min(remaining, self.cfl * t.stable_dt())
            if sub >= remaining * (1.0 - 1e-12):
                sub = remaining
            t.step(sub)
            remaining -= sub
        if rest is not None:  # nodes off the set were dry before and after (CFL <= 1)
            state = self._state(nodes)
            state[:, 1], state[:, 2] = spend_capacity(state[:, 1], state[:, 2], rest)
            self._set_state(nodes, state)

    def _state(self, nodes: np.ndarray | None) -> np.ndarray:
        """Return the state at ``nodes`` (None: every local node)."""
        t = self.transport
        return t.state() if nodes is None else t.state_on(nodes)

    def _set_state(self, nodes: np.ndarray | None, state: np.ndarray) -> None:
        """Set the state at ``nodes`` (None: every local node) after a friction step.

        The callers change the momenta only, and friction keeps them zero where the node is
        dry: the transport's active-set test still holds (``depth_kept``).
        """
        t = self.transport
        if nodes is None:
            t.set_state(state)
        else:
            t.set_state_on(nodes, state, depth_kept=True)

    def _unused_capacity(self, state: np.ndarray, dt: float, nodes: np.ndarray | None,
                         bed: BedFrame | None = None) -> np.ndarray | None:
        """Coulomb capacity D leaves, per node (:meth:`FrictionLaw.unused_capacity`), or None.

        Strang's ``T(dt/2) D(dt) T(dt/2)`` ends with a transport half step that gives a layer
        at rest on a slope the impulse ``g S h dt/2``; what D's capacity ``dt g μ h`` has left
        after stopping the node holds it. Giving the second half its own full capacity
        ``dt/2 g μ h`` instead stopped a decelerating sheet up to a quarter step early
        (Coulomb stop test). ``state`` holds the rows of ``nodes`` (None: every local node);
        ``bed`` is :meth:`DiffusionReaction.bed` of it, if known.
        """
        friction = self.reaction.friction if self.reaction is not None else None
        if friction is None:
            return None
        if bed is None:
            bed = self.reaction.bed(state[:, 1:], nodes)
        return friction.unused_capacity(state[:, 0], state[:, 1], state[:, 2], dt, bed)

    def snapshot(self) -> tuple[np.ndarray | None, np.ndarray, tuple[float, float]]:
        """Copy the state, to restore the last good step (valid until the next snapshot).

        Only the flow's nodes when the state is known to be zero elsewhere (the transport's
        active set, friction only: the next step writes no other node); else every node,
        into one buffer reused from step to step.
        """
        t = self.transport
        nodes = t.flow_nodes() if self.reaction is None or self.reaction.rheology is None \
            else None
        volumes = (t.outflow_volume, t.dried_volume)
        if nodes is None:
            self._snap = t.state(self._snap)
            return None, self._snap, volumes
        return nodes, t.state_on(nodes), volumes

    def restore(self, snap: tuple[np.ndarray | None, np.ndarray, tuple[float, float]]) -> None:
        """Restore a :meth:`snapshot`."""
        nodes, q, (outflow, dried) = snap
        t = self.transport
        if nodes is None:
            t.set_state(q)
        else:
            full = np.zeros((t.h.x.array.size, 3))
            full[nodes] = q
            t.set_state(full)
        t.outflow_volume, t.dried_volume = outflow, dried
        self._limits = None

    def save_state(self) -> dict:
        """Return ``(h, hu, hv)`` in the global node order, outflow and dried (collective)."""
        from fem_runout.output.gather import gather_nodal

        t = self.transport
        q = t.state()
        arrays = {"h": q[:, 0], "hu": q[:, 1], "hv": q[:, 2]}
        if t.active_set and t.active.seed is not None:
            arrays["active_seed"] = t.active.seed  # the wet nodes the active set was built on
        return {"nodes": gather_nodal(self.V, arrays), "outflow": float(t.outflow_volume),
                "dried": float(t.dried_volume)}

    def load_state(self, state: dict) -> None:
        """Continue from :meth:`save_state` (collective; any rank count)."""
        from fem_runout.checkpoint import scatter_nodal

        t = self.transport
        local = scatter_nodal(self.V, state["nodes"])
        t.set_state(np.stack([local["h"], local["hu"], local["hv"]], axis=1))
        t.outflow_volume = float(state["outflow"])
        t.dried_volume = float(state.get("dried", 0.0))  # checkpoints before the drying: 0
        self._limits = None
        if t.active_set and "active_seed" in local:
            t.active.rebuild(local["active_seed"])  # the uninterrupted run's very set

    def flow_dofs(self) -> np.ndarray:
        """Owned nodes of the transport's active set (the state is zero outside it).

        With a rheology the reaction step works on every node: then every owned node. (No
        reaction at all: frictionless transport, also only the active set.)
        """
        n = self.V.dofmap.index_map.size_local
        if self.reaction is not None and self.reaction.rheology is not None:
            return np.arange(n)
        nodes = self.transport.active.nodes
        return nodes[nodes < n]

    def health(self, also_max: np.ndarray | None = None) -> str | None:
        """Check the state (collective): a message if it has NaN or negative depth, else None.

        ``also_max`` is maximised over the ranks in the same reduction (in place), and so is
        the next :meth:`stable_dt` (the transport's low-order pass of this state, kept for
        the next step): one reduction for the step's check and the next step's size.
        """
        n, t = self.disc.n_owned_nodes, self.transport
        h = t.h.x.array
        local = state_flag(h, t.hu.x.array, t.hv.x.array, n)
        with np.errstate(all="ignore"):  # a bad state still takes part in the pass's exchange
            limits = self.transport.local_limits(with_slope=True)
        worst = reduce_flag(self.comm, local, limits, also_max)
        if worst == 0:
            self._limits = self.transport.limits_from(limits)
        if worst == 2:
            return "the state has NaN or infinite values"
        if worst == 1:
            hmin = self.comm.allreduce(float(h[:n].min()) if n else 0.0, op=MPI.MIN)
            return f"negative depth {hmin:.3e} m"
        return None


def build_tg2(case: Case, comm: MPI.Comm) -> TG2Solver:
    """Create the TG2-PC solver of a case (collective): the shared setup plus its operators."""
    pb = build_problem(case, comm)
    num = case.numerics
    transport = Transport(pb.disc, pb.gravity, num.dry_tolerance, pb.thin_depth, num.fct,
                          pb.slope, num.active_set, num.mass_correction, num.step_bound)
    for name in ("z", "h", "hu", "hv"):
        getattr(transport, name).x.array[:] = pb.init[name]
    reaction = None
    if pb.friction is not None or pb.rheology is not None:
        reaction = DiffusionReaction(pb.disc, transport.h, pb.friction, pb.rheology,
                                     num.dry_tolerance, pb.thin_depth, pb.slope)
    return TG2Solver(pb.disc, transport, reaction, case.time.cfl)
