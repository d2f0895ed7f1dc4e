"""DAMPM's Coulomb stop (its own at-rest checks), for every method with particles; the Voellmy
sheet and the held layer run for every method in tests/test_tg2_physics.py.

The sheets are open downstream as for TG2-PC: DAMPM's open sides carry the pressure of the
fluid beyond (transmissive), so they launch no rarefaction into the probe window.
"""

import numpy as np
import pytest

from fem_runout.methods import METHODS
from tests.tg2_helpers import G, probe, sheet


@pytest.mark.parametrize("method", [m.name for m in METHODS.values() if m.particles])
def test_coulomb_stop_time_and_no_creep(method):
    slope, mu, u0 = 0.1, 0.3, 5.0
    t_stop = u0 / (G * (mu - slope))
    c = sheet(slope, {"law": "coulomb", "mu": mu}, u0=u0, end=2.0 * t_stop, method=method)
    t, u, umax = probe(c)
    # at rest: the grid momentum is h times the mass-averaged particle velocity, exactly 0
    k = np.flatnonzero(np.abs(u) <= 1e-12)[0]
    rate = (u[k - 2] - u[k - 1]) / (t[k - 1] - t[k - 2])
    crossing = t[k - 1] + u[k - 1] / rate
    print(f"{method} Coulomb stop at {crossing:.4f} s, exact {t_stop:.4f} s; deceleration "
          f"{rate:.4f}, exact {G * (mu - slope):.4f}")
    assert abs(crossing / t_stop - 1.0) < 0.02
    assert t[k - 1] < t_stop <= t[k] + 1e-9
    assert np.all(np.diff(u[: k + 1]) <= 1e-12)
    assert np.abs(umax[k:]).max() <= 1e-12



class _HeldDepths:
    """Runner callback: depth changes of particles friction holds (``v_p = 0`` exactly)."""

    def __init__(self) -> None:
        self.before: dict[int, float] = {}
        self.held, self.changed, self.moving = 0, 0.0, 0

    def start(self, solver, info) -> None:
        self.before = dict(zip(solver.particles.id.tolist(), solver.particles.h.tolist(),
                               strict=True))

    def step(self, solver, info) -> None:
        p = solver.particles
        still = (p.u == 0.0) & (p.v == 0.0)
        self.moving += int((~still).sum())
        for i, h in zip(p.id[still].tolist(), p.h[still].tolist(), strict=True):
            if i in self.before:
                self.held += 1
                self.changed = max(self.changed, abs(h / self.before[i] - 1.0))
        self.start(solver, info)

    def output(self, solver, info) -> None:
        pass

    def finish(self, solver, info) -> None:
        pass


@pytest.mark.parametrize("method", [m.name for m in METHODS.values() if m.particles])
def test_material_held_by_friction_keeps_its_depth(method):
    """A moving layer runs into one friction holds: the held particles' columns do not change.

    Eq. 42 takes the strain from the re-mapped nodal velocity, a mass-weighted average that
    reaches the held nodes from the moving particles next to them; unscaled, a particle at
    rest in a deposit kept thickening as long as the flow beside it crept (a 4 cm remnant of
    avaKot grew to 7e4 m in 150 s and its wave speed collapsed the step).
    """
    from mpi4py import MPI

    from fem_runout.api import build_solver
    from fem_runout.runner import Runner, Schedule

    c = sheet(0.0, {"law": "coulomb", "mu": 0.3}, u0="maximum(0, 3 - x / 40)", end=1.0,
              method=method)
    solver = build_solver(c, MPI.COMM_SELF)
    held = _HeldDepths()
    Runner(solver, Schedule(c.time.end, c.time.cfl, c.output.every), [held]).run()
    print(f"{method}: {held.held} held particle-steps, {held.moving} moving; largest "
          f"relative depth change of a held particle {held.changed:.3g}")
    assert held.held > 1000 and held.moving > 1000
    assert held.changed == 0.0


@pytest.mark.parametrize(("cap", "bound"), [(3.0, 4.0), (None, None)], ids=["cap", "seed"])
def test_particle_columns_piling_at_a_wall_stay_near_the_grid_depth(cap, bound):
    """The cliff hard case to 3 s: the flow runs into the wall at x = 60 m and reflects.

    Eq. 42 alone lets the piled particles' columns drift far above any depth the flow has on
    the grid (about 50 times the largest grid depth here; 700 m particles over a 5 m bore),
    and their pressure and wave speed follow. With the depth cap ``κ`` no particle is thicker
    than ``κ`` times the grid depth where it is before its step; one step of eq. 42 (CFL
    bounded) adds less than a factor 4/3: the bound is ``κ + 1``.
    """
    from mpi4py import MPI

    from fem_runout.api import build_solver
    from fem_runout.config import load_case
    from tests.tg2_helpers import CASES

    overrides = ["method=mpm", "time.end=3.0", f"numerics.depth_cap={cap or 'null'}"]
    solver = build_solver(load_case(CASES / "hard" / "cliff.yaml", overrides), MPI.COMM_SELF)
    t, ratio = 0.0, 0.0
    while t < 3.0:
        dt = min(0.9 * solver.stable_dt(), 3.0 - t)
        solver.advance(dt)
        t += dt
        ratio = max(ratio, solver.particles.h.max() / solver.fields["h"].x.array.max())
    print(f"depth cap {cap}: largest particle depth / largest grid depth {ratio:.3g}")
    assert ratio <= bound if cap else ratio > 20.0
