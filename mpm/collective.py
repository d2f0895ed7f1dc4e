"""The collective parts of a DAMPM step: its few messages, and the state in and out.

A usual step sends four messages (docs/dampm.md, "Parallel runs"): the P2G bounds with the
ids of the children the last split made (:meth:`CollectiveSteps._particle_terms`), the touched
nodes' mask and the P2G sums (:class:`mpm.exchange.FoldExchange`), and the MUSL momentum's sums
(:meth:`CollectiveSteps._momentum_sums`). :class:`mpm.solver.MPMSolver` inherits these methods;
they read its particles, grid, kernels, splitter and exchange.
"""

from __future__ import annotations

import numpy as np

from fem_runout.exact_sum import extractors, fold_extractors
from mpm.exchange import p2g_bounds, p2g_bounds_of
from mpm.migrate import balanced_destinations, migrate
from mpm.particles import FLOAT_FIELDS, Particles

__all__ = ["CollectiveSteps"]


class CollectiveSteps:
    """The messages of :class:`mpm.solver.MPMSolver`'s step and its state I/O (a mix-in)."""

    #: DAMPM dries no films: its particles keep their volume until they leave the domain
    dried_volume = 0.0

    def save_state(self) -> dict:
        """Return every particle (all attributes, sorted by id) and counters (collective)."""
        rows = self.comm.gather(self.particles.pack(), root=0)
        if rows is not None:
            rows = np.concatenate(rows)
            rows = rows[np.argsort(rows[:, -1].copy().view(np.int64), kind="stable")]
        return {"particles": rows, "outflow": float(self.outflow_volume),
                "next_id": int(self.splitter.next_id), "split_count": int(self.splitter.count)}

    def load_state(self, state: dict) -> None:
        """Continue from :meth:`save_state` (collective; any rank count)."""
        width = len(FLOAT_FIELDS) + 2
        rows = state["particles"] if self.comm.rank == 0 else np.zeros((0, width))
        p = Particles.unpack(np.asarray(rows, dtype=np.float64), self.apic,
                             self.particles.has_quad)
        self.particles, _ = migrate(self.grid, p, balanced_destinations(self.grid, p))
        self.outflow_volume = float(state["outflow"])
        self.splitter.next_id = int(state["next_id"])
        self.splitter.count = int(state["split_count"])
        self._problem = None
        self._pending = None
        self._refresh()

    def _settle_split(self) -> None:
        """Settle the pending children's ids with a message of their own (collective)."""
        pending, self._pending = self._pending, None
        if pending is not None and self.splitter.settle(
                self.particles, pending, self.comm.allgather(pending.payload)):
            self.particles = self.splitter.split(self.particles)

    def _particle_terms(self) -> tuple[np.ndarray, ...]:
        """Basis, forces and P2G bounds of the particles (collective: one message as a rule).

        The ids of the last split's children (:attr:`_pending`) are settled with the bounds'
        message (:meth:`mpm.split.DomainSplitter.settle`); if a domain is still too wide the
        particles are split again and the terms recomputed.

        Returns:
            ``(mass, area, forces, local, bounds, union)``: the particles' masses and column
            areas, and :func:`mpm.exchange.p2g_bounds`'s.
        """
        while True:
            p, g = self.particles, self.grid
            self._basis = b = g.particle_basis(p)
            forces, self._gp, self._slope, self._speed = self.k.particle_forces(
                b.arrays, self.z_g, self._hess, self._still, self.rho, self.g, p.volume,
                p.h, p.u, p.v, p.sxx, p.syy, p.sxy)
            mass, area = self.rho * p.volume, p.area
            speeds = p.transfer_speeds(g.dx, g.dy, self.apic)
            local = self.k.transfer_bounds(b.arrays, mass, *speeds, forces, area, p.volume)
            pending, self._pending = self._pending, None
            if pending is None:
                return mass, area, forces, local, *p2g_bounds(local, self.comm)
            sent = self.comm.allgather((pending.payload, local.tobytes()))
            if not self.splitter.settle(p, pending, [s[0] for s in sent]):
                bounds = p2g_bounds_of([np.frombuffer(s[1], dtype=local.dtype) for s in sent])
                return mass, area, forces, local, *bounds
            self.particles = self.splitter.split(p)  # rare: a domain more than twice too wide

    def _momentum_sums(self, mass: np.ndarray, top: np.ndarray) -> np.ndarray:
        """Exact nodal sums of the MUSL momentum (collective: one message as a rule).

        The exact sums' extractors need a bound of every ``|m_p s_p|`` over the ranks
        (``top`` here, this rank's maxima). Twice the step's start bound (:attr:`_musl_bound`,
        known on every rank from :func:`mpm.exchange.p2g_bounds`) holds unless a particle more
        than doubled its largest ``m |v|`` within the step: each rank checks its own maxima,
        and the flag rides in the sums' message; only if some rank exceeds it (the release's
        first step, from rest) are the sums redone with the maxima reduced over the ranks.
        Either way every rank uses the same extractors, so the sums have the same bits on any
        rank count.
        """
        p, b = self.particles, self._basis

        def folds(ext: np.ndarray) -> np.ndarray:
            return self.k.p2g_momentum(b.arrays, mass, p.u, p.v, p.affine(), self._box_args, ext)

        flag = np.array([0.0 if (top <= self._musl_bound).all() else 1.0])
        mom = self.exchange.sum(folds(fold_extractors(self._musl_bound, self.splitter.next_id)),
                                flag)
        if flag[0] == 0.0:
            return mom
        return self.exchange.sum(folds(extractors(top, self.splitter.next_id, self.comm)))
