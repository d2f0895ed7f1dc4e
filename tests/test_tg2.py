"""TG2-PC transport: well-balancing, positivity, conservation, convergence, symmetry."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.methods import get
from fem_runout.references.inclined_dam_break import exact_front
from fem_runout.references.norms import front_radius, l1, nodal_weights
from fem_runout.references.ritter import ritter_depth
from fem_runout.tg2.solver import build_tg2
from tests.tg2_helpers import case, lake_errors

COMM = MPI.COMM_SELF
#: A strip of the inclined dam break's channel three of its 33 cells wide (same cell shape).
STRIP = f"domain.extent=[0, 300, 0, {20 * 3 / 33!r}]"


def test_lake_at_rest_is_exact():
    """Seed §4.2: three bumps, two of them dry, walls, T = 1 s: errors <= 1e-12."""
    result = run(case("lake_at_rest"), write=False, comm=COMM)
    errors = lake_errors(result)
    print("lake at rest (L1, Linf):", errors)
    assert (result.h == 0).sum() > 0, "the case must have dry bumps"
    for name, (e1, einf) in errors.items():
        assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)


class _Watch:
    """Callback recording min depth and volume after every step."""

    def __init__(self):
        self.min_h, self.volumes = [], []

    def start(self, solver, info):
        self.step(solver, info)

    def step(self, solver, info):
        own = slice(0, solver.disc.n_owned_nodes)
        h = solver.fields["h"].x.array[own]
        self.min_h.append(h.min())
        # the volume on the nodes plus the films that dried out (serial: one rank's sum)
        self.volumes.append(float(np.sum(solver.lumped_mass[own] * h)) + solver.dried_volume)

    def output(self, solver, info):
        pass

    def finish(self, solver, info):
        pass


def test_closed_box_conserves_mass_and_keeps_depth_non_negative():
    """Hemisphere collapse in a walled box, run past the wall reflection."""
    from fem_runout.runner import Runner, Schedule

    c = case("hemisphere", "domain.extent=[15,35,15,35]", "domain.cells=[40,40]",
             "domain.boundary=wall", "time.end=3.0")
    solver = build_tg2(c, COMM)
    watch = _Watch()
    info = Runner(solver, Schedule(3.0, 0.9, 3.0), [watch]).run()
    vols = np.array(watch.volumes)
    rel = np.abs(vols - vols[0]).max() / vols[0]
    print(f"steps {info.step}, max relative mass error {rel:.2e}, min h {min(watch.min_h):.2e}")
    assert info.step > 50
    assert rel <= 1e-12
    assert min(watch.min_h) >= 0.0


def _ritter_l1(nx: int) -> float:
    c = case("ritter", f"domain.cells=[{nx},2]", "output.every=4.0")
    r = run(c, write=False, comm=COMM)
    exact = ritter_depth(r.x, 4.0, 1.0, 50.0, 9.81)
    return l1(r.h - exact, nodal_weights(r.x, r.y)) / 2.0  # per unit width


def test_ritter_converges():
    errors = [_ritter_l1(nx) for nx in (100, 200, 400)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    print("Ritter L1 errors", errors, "observed orders", orders)
    assert errors[0] > errors[1] > errors[2]
    assert orders.min() > 0.9  # first order: the dry front limits any scheme to ~1
    assert errors[-1] < 0.16  # m² per metre of width, at dx = 0.25 m


def test_hemisphere_front_is_isotropic():
    """Seed §4.1.1: front radius equal in x, y and diagonal directions within one cell."""
    r = run(case("hemisphere"), write=False, comm=COMM)
    dxc = 50.0 / 100
    radii = {name: front_radius(r.x, r.y, r.h, (25.0, 25.0), 1e-3, d) for name, d in {
        "x": (1.0, 0.0), "y": (0.0, 1.0), "-x": (-1.0, 0.0),
        "diag": (np.sqrt(0.5), np.sqrt(0.5))}.items()}
    print("hemisphere front radii at 1.2 s:", radii)
    values = np.array(list(radii.values()))
    assert values.min() > 5.0 + 2 * dxc  # it spread
    assert values.max() - values.min() <= np.sqrt(2.0) * dxc  # one cell (diagonal spacing)
    assert abs(radii["x"] - radii["y"]) < 1e-9 and abs(radii["x"] - radii["-x"]) < 1e-9


@pytest.mark.slow
def test_inclined_dam_break_front_approaches_exact_tip():
    """Seed §4.1 at the paper's resolution (dx = 0.91 m, dy = 0.61 m) and two finer grids.

    The flow does not depend on y, so each level runs on a strip three of the paper's cells
    wide (``STRIP``): the same cells give the same nodal depths as the 20 m channel to round-off
    (``test_a_strip_of_the_channel_gives_the_channels_answer``) at a tenth of the cost.
    The front is where h falls to 1e-3 m along the bottom wall, interpolated between nodes
    (continuous in the data). A front on a grid is resolved to about a cell, so a finer level
    may not fall behind a coarser one by more than the coarser cell (dx = 0.91, 0.45 m); over
    the whole ladder the gap to the exact dry-bed tip must shrink, and no front may pass it.
    """
    levels = [(330, 3), (660, 3), (1320, 3)]
    fronts = {}
    for nx, ny in levels:
        c = case("inclined_dam_break", f"domain.cells=[{nx},{ny}]", STRIP, "output.every=2.75",
                 "time.end=8.25")
        fronts[nx] = _fronts(c, (2.75, 5.5, 8.25))
    for t in (2.75, 5.5, 8.25):
        row = [fronts[nx][t] for nx, _ in levels]
        print(f"t={t}: fronts {row} exact {exact_front(t):.2f} paper TG2(5.5 s) "
              f"{get("tg2").paper["front"][5.5]}")
        gaps = [exact_front(t) - f for f in row]
        for (nx, _), coarse, fine in zip(levels[:-1], gaps[:-1], gaps[1:], strict=True):
            assert fine <= coarse + 300.0 / nx, (t, gaps)
        assert gaps[0] > gaps[2] and min(gaps) > 0.0, (t, gaps)
    assert fronts[1320][5.5] > get("tg2").paper["front"][5.5]


def _fronts(c, times):
    from fem_runout.runner import Runner, Schedule

    solver = build_tg2(c, COMM)
    found = {}

    class Front:
        def start(self, s, i): pass
        def step(self, s, i): pass
        def finish(self, s, i): pass

        def output(self, s, i):
            x, y = s.disc.coords[:, 0], s.disc.coords[:, 1]
            found[round(i.t, 6)] = front_radius(x, y, s.fields["h"].x.array, (0.0, 0.0),
                                                1e-3, (1.0, 0.0))

    Runner(solver, Schedule(max(times), 0.9, times[0]), [Front()]).run()
    return {t: found[round(t, 6)] for t in times}


def test_a_strip_of_the_channel_gives_the_channels_answer():
    """Three of the paper's 33 cells across, walls on both sides: the same nodal depths.

    Every cell has the paper's shape, and the flow is y-invariant, so the strip only drops
    nodes that repeat a column; the depths agree to round-off (1e-10 m on depths of 1 m).
    """
    common = ("time.end=2.75", "output.every=2.75")
    full = run(case("inclined_dam_break", *common), write=False, comm=COMM)
    strip = run(case("inclined_dam_break", "domain.cells=[330,3]", STRIP, *common),
                write=False, comm=COMM)
    bottom = full.h.reshape(34, 331)[0]
    assert full.steps == strip.steps and bottom.max() > 0.5
    assert np.abs(strip.h.reshape(4, 331) - bottom).max() <= 1e-10


def test_y_invariant_dam_break_stays_y_invariant():
    """The inclined dam break does not depend on y: no transverse variation may grow."""
    r = run(case("inclined_dam_break", "time.end=3.0", "output.every=3.0"), write=False,
            comm=COMM)
    depth = r.h.reshape(34, 331)
    mean = depth.mean(axis=0)
    spread = (depth.max(axis=0) - depth.min(axis=0))[mean > 0.01] / mean[mean > 0.01]
    print(f"transverse spread / depth: median {np.median(spread):.1e}, max {spread.max():.1e}")
    assert np.median(spread) < 1e-9 and spread.max() < 1e-5


class _ActiveSpy:
    """Records the active-set size after the first step and the number of rebuilds."""

    def start(self, solver, info):
        self.solver, self.first = solver, None

    def step(self, solver, info):
        if self.first is None:
            self.first = solver.transport.active.active_cells

    def output(self, solver, info):
        pass

    def finish(self, solver, info):
        self.rebuilds = solver.transport.active.rebuilds
        self.cells = solver.disc.cell_nodes.shape[0]


def test_the_active_set_gives_the_same_bits_as_the_whole_mesh():
    """Issue 16: a dry-bed dam break whose front crosses the whole strip and leaves it."""
    from fem_runout.references.stoker import dam_break_case

    base = dam_break_case(1.0, 0.0, 10.0, (200, 4), 16.0)
    spy = _ActiveSpy()
    on = run(load_case(base), write=False, comm=COMM, callbacks=[spy])
    off = run(load_case(base, [("numerics.active_set", False)]), write=False, comm=COMM)
    print(f"active set: {spy.first} of {spy.cells} cells after the first step, "
          f"{spy.rebuilds} rebuilds in {on.steps} steps; peak depth at the far end "
          f"{on.peak_depth[on.x == on.x.max()].max():.3g} m")
    assert spy.first < 0.2 * spy.cells and spy.rebuilds > 5
    assert on.peak_depth[on.x == on.x.max()].max() > 0.0  # the front crossed the strip
    for key in ("h", "hu", "hv", "peak_depth", "peak_speed"):
        assert np.array_equal(getattr(on, key), getattr(off, key)), key


def test_the_active_set_test_rides_with_the_steps_last_message():
    """The set's edge test of a step's new state travels in the step's last exchange.

    The test is made on the new depth (after a step the momenta vanish with the depth, and
    friction keeps them so): a solver that tests in every low-order pass with a reduction of
    its own takes the same decisions (rebuilds) and steps to the bit, and the carried test
    saves that reduction, two a split step (a rebuild's decision needs none either).
    """
    from tests.counting_comm import CountingComm

    c = case("hemisphere", "domain.cells=[40,40]", "material.friction.law=voellmy",
             "material.friction.mu=0.2", "material.friction.xi=500")
    carried, tested = (build_tg2(c, COMM) for _ in range(2))
    own = tested.transport._low_order_pass

    def pass_with_own_test():
        tested.transport._inside = None  # the former way: the pass tests and reduces
        own()

    tested.transport._low_order_pass = pass_with_own_test
    counts = []
    for solver in (carried, tested):
        solver.health()  # the first pass, on the state set at the start
        counting = CountingComm(COMM)
        solver.comm = solver.disc.comm = counting
        for _ in range(25):
            solver.advance(0.9 * solver.stable_dt())
            assert solver.health() is None
        counts.append(counting.calls["allreduce"])
    for name in ("h", "hu", "hv"):
        assert np.array_equal(carried.fields[name].x.array, tested.fields[name].x.array), name
    rebuilds = carried.transport.active.rebuilds
    print(f"{rebuilds} rebuilds; allreduce calls in 25 steps: {counts[0]} carried, "
          f"{counts[1]} tested in the pass")
    assert rebuilds == tested.transport.active.rebuilds >= 4
    assert counts[0] == 0 and counts[1] >= 2 * 25  # two passes a step (more if it splits)
