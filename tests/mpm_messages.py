"""How many messages a DAMPM step sends, on any communicator (serial and MPI tests)."""

from __future__ import annotations

import numpy as np

from fem_runout.api import build_solver
from tests.counting_comm import CountingComm
from tests.tg2_helpers import case

#: A pile with Voellmy friction that starts at rest: its first step's MUSL sums fall back.
PILE = ("method=mpm", "domain.cells=[16,16]", "material.friction.law=voellmy",
        "material.friction.mu=0.2", "material.friction.xi=500")


def count_messages(comm, steps: int = 3) -> tuple[CountingComm, object]:
    """Build the pile, take one step, then ``steps`` counted steps (no rebalancing among them).

    Each step is followed by the health check, as in the runner (it also reduces the next
    step's limits). Every reference of the solver and its parts to ``comm`` is replaced by
    one counter.
    """
    solver = build_solver(case("hemisphere", *PILE), comm)
    dt = 0.5 * solver.stable_dt()
    solver.advance(dt)
    assert solver.health() is None
    p = solver.particles
    p.lx[::7] *= 2.1  # wider than the split limit along x and y: the next step splits them
    p.ly[::5] *= 2.1  # in both passes
    counting = CountingComm(comm)
    for owner in (solver, solver.grid, solver.exchange, solver.nodal):
        owner.comm = counting
    for _ in range(steps):
        solver.advance(dt)
        assert solver.health() is None
    return counting, solver


def momentum_sums_both_ways(solver) -> tuple[np.ndarray, np.ndarray]:
    """The MUSL momentum sums with the step's bound and with the bound reduced over the ranks.

    The second forces the fallback: a bound of zero is exceeded by any moving particle.
    """
    p = solver.particles
    mass = solver.rho * p.volume
    top = np.array([np.abs(mass * p.u).max(initial=0.0), np.abs(mass * p.v).max(initial=0.0)])
    quick = solver._momentum_sums(mass, top)
    bound, solver._musl_bound = solver._musl_bound, np.zeros(2)
    try:
        full = solver._momentum_sums(mass, top)
    finally:
        solver._musl_bound = bound
    return quick, full
