"""DAMPM (seed §3.2): well-balancing, conservation, positivity, fronts, symmetry, output."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import build_solver, run
from fem_runout.methods import get
from fem_runout.references.inclined_dam_break import exact_front
from fem_runout.references.norms import front_radius
from fem_runout.runner import Runner, Schedule
from tests.mpm_messages import PILE
from tests.tg2_helpers import case, lake_errors

COMM = MPI.COMM_SELF
FULL = ("material.friction={law: voellmy, phi_deg: 26, xi: 500}",
        "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}")


def test_lake_at_rest_with_full_rheology_is_exact():
    """Seed §4.2, Table 2 (DAMPM: L1 1.26e-12, Linf 1.26e-14 for h)."""
    keep = _Keep()
    r = run(case("lake_at_rest", "method=mpm", *FULL), write=False, comm=COMM, callbacks=[keep])
    solver, start = keep.solver, keep.initial
    errors = lake_errors(r)
    print(f"DAMPM lake at rest after {r.steps} steps:", errors)
    assert r.t == 1.0 and r.steps > 100
    for name, (e1, einf) in errors.items():
        assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)
    p = solver.particles  # the particles themselves are exactly at rest
    assert np.array_equal(p.id, start.id) and np.array_equal(p.h, start.h)
    assert np.array_equal(p.xi, start.xi) and np.abs(p.u).max() == 0.0


class _Keep:
    """Keeps the run's solver and a copy of its particles at the start."""

    def start(self, solver, info):
        self.solver, self.initial = solver, solver.particles.copy()

    def step(self, solver, info): pass
    def output(self, solver, info): pass
    def finish(self, solver, info): pass


class _Watch:
    """Grid volume, particle volume and min depth after every step."""

    def __init__(self):
        self.grid, self.particles, self.min_h = [], [], []

    def _record(self, s, info):
        own = slice(0, s.disc.n_owned_nodes)
        self.grid.append(float(np.sum(s.lumped_mass[own] * s.fields["h"].x.array[own])))
        self.particles.append(s.particle_volume() + s.outflow_volume)
        self.min_h.append(float(s.fields["h"].x.array.min()))

    start = step = _record

    def output(self, s, info):
        pass

    def finish(self, s, info):
        pass


def test_mass_is_exact_and_projection_keeps_volume_and_positivity():
    """Closed box past the wall reflection, with friction and rheology."""
    c = case("hemisphere", "method=mpm", "domain.extent=[15,35,15,35]", "domain.cells=[40,40]",
             "domain.boundary=wall", "time.end=3.0", *FULL)
    solver = build_solver(c, COMM)
    volume0 = float(solver.particles.volume.sum())
    exact0 = math.fsum(solver.particles.volume)
    n0 = solver.n_particles
    watch = _Watch()
    info = Runner(solver, Schedule(3.0, 0.9, 3.0), [watch]).run()
    grid, parts = np.array(watch.grid), np.array(watch.particles)
    print(f"steps {info.step}: particle volume drift {abs(parts[-1] - volume0):.1e}, "
          f"max |grid - particle| / V = {np.abs(grid - parts).max() / volume0:.2e}")
    assert info.step > 50 and solver.n_particles == n0 + solver.splitter.count  # none lost
    # fixed particle masses, none lost; splitting halves them exactly (exactly rounded sums)
    assert math.fsum(solver.particles.volume) == exact0
    assert abs(parts[-1] - volume0) <= 1e-14 * volume0
    assert np.abs(grid - parts).max() <= 1e-12 * volume0
    assert min(watch.min_h) >= 0.0


def test_open_boundary_outflow_balances_the_volume():
    r = run(case("inclined_dam_break", "method=mpm", "domain.cells=[330,3]", "time.end=11"),
            write=False, comm=COMM)
    s = r.series
    balance = s["volume"] + s["outflow"] - s["volume"][0]
    print("outflow", s["outflow"][-1], "max balance error", np.abs(balance).max())
    assert s["outflow"][-1] > 0.02 * s["volume"][0]  # particles did leave
    assert np.abs(balance).max() <= 1e-12 * s["volume"][0]


def test_hemisphere_front_is_isotropic():
    """Seed §4.1.1: front radius equal in x, y and diagonal directions within one cell."""
    r = run(case("hemisphere", "method=mpm"), write=False, comm=COMM)
    dxc = 50.0 / 100
    radii = {name: front_radius(r.x, r.y, r.h, (25.0, 25.0), 1e-3, d) for name, d in {
        "x": (1.0, 0.0), "y": (0.0, 1.0), "-x": (-1.0, 0.0), "-y": (0.0, -1.0),
        "diag": (np.sqrt(0.5), np.sqrt(0.5))}.items()}
    print("DAMPM hemisphere front radii at 1.2 s:", radii)
    values = np.array(list(radii.values()))
    assert values.min() > 5.0 + 2 * dxc
    assert values.max() - values.min() <= np.sqrt(2.0) * dxc


def _front(nx, ny, t=5.5):
    c = case("inclined_dam_break", "method=mpm", f"domain.cells=[{nx},{ny}]", f"time.end={t}",
             f"output.every={t}")
    return run(c, write=False, comm=COMM)


def test_inclined_dam_break_front_approaches_exact_tip():
    """Seed §4.1: y-invariant dam break on x-refined grids (dy fixed)."""
    fronts = {}
    for nx in (165, 330, 660, 1320):
        r = _front(nx, 3)
        fronts[nx] = r.series["front_x"][-1]
    tip = exact_front(5.5)
    print(f"DAMPM fronts at 5.5 s: {fronts}, exact tip {tip:.1f}, paper DAMPM "
          f"{get("mpm").paper["front"][5.5]}")
    gaps = [tip - fronts[nx] for nx in (165, 330, 660, 1320)]
    assert gaps[0] > gaps[1] > gaps[2] > gaps[3] > -1.0
    assert fronts[330] > get("mpm").paper["front"][5.5]


def test_a_strip_of_the_channel_gives_the_channels_answer():
    """Seed §4.1 on 3 of 11 rows across, walls on both sides: the same nodal depths and steps.

    The flow is y-invariant, so the strip drops particles and nodes that repeat a column; the
    benchmark ladders' tests run the dam break on such strips (``tests/test_references.py``).
    """
    common = ("method=mpm", "time.end=2.75", "output.every=2.75")
    full = run(case("inclined_dam_break", "domain.cells=[165,11]", *common), write=False,
               comm=COMM)
    strip = run(case("inclined_dam_break", "domain.cells=[165,3]",
                     f"domain.extent=[0, 300, 0, {20 * 3 / 11!r}]", *common),
                write=False, comm=COMM)
    bottom = full.h.reshape(12, 166)[0]
    assert full.steps == strip.steps and bottom.max() > 0.5
    assert np.abs(strip.h.reshape(4, 166) - bottom).max() <= 1e-10


def test_particle_cloud_is_written_for_paraview(tmp_path, monkeypatch):
    import pyvista as pv

    monkeypatch.chdir(tmp_path)
    c = case("hemisphere", "method=mpm", "domain.cells=[40,40]", "time.end=0.4",
             "output.every=0.2", "output.pictures=false")
    r = run(c, write=True, comm=COMM)
    pvd = (r.out_dir / "particles.pvd").read_text()
    assert pvd.count("<DataSet") == 3 and 'timestep="0.4"' in pvd
    path = r.out_dir / "particles" / "particles_0002.vtp"
    assert 'compressor="vtkLZ4DataCompressor"' in path.read_bytes()[:400].decode("latin-1")
    cloud = pv.read(path)
    assert cloud.n_points == r.particles
    assert np.unique(cloud.point_data["id"]).size == cloud.n_points
    volume = float(cloud.point_data["volume"].sum())
    assert volume == pytest.approx(r.series["volume"][-1], rel=1e-12)
    assert np.allclose(cloud.points[:, 2], 0.0)  # particles sit on the (flat) terrain


def test_a_collapsing_column_stops_the_run_with_the_state_kept():
    """Seed eq. 42 with ``1 + Δt tr L <= 0``: a message, no negative or infinite depth."""
    solver = build_solver(case("hemisphere", "method=mpm"), COMM)
    assert solver.health() is None
    p = solver.particles
    h0 = p.h.copy()
    grad = np.zeros((len(p), 2, 2))
    grad[:, 0, 0] = grad[:, 1, 1] = -0.25  # converging: 1 + dt tr = 1 - 0.5 dt
    grad[7, 0, 0] = -2.0  # one column squeezed past zero at dt = 0.5
    solver.update_depth_and_stress(0.5, grad)
    message = solver.health()
    assert message is not None and "collapsed" in message and f"particle {p.id[7]}" in message
    assert np.array_equal(solver.particles.h, h0)
    solver.update_depth_and_stress(0.5, np.where(np.arange(len(p))[:, None, None] == 7,
                                                  0.0, grad))
    assert np.allclose(solver.particles.h[:7], h0[:7] / 0.75, rtol=1e-15)


def test_dampm_health_names_non_finite_particle_values():
    """A NaN or an infinite depth or velocity on any particle fails the step's health check."""
    solver = build_solver(case("hemisphere", *PILE), COMM)
    solver.advance(0.5 * solver.stable_dt())
    assert solver.health() is None
    p = solver.particles
    for name, value in (("u", np.nan), ("v", -np.inf), ("h", np.inf)):
        column = getattr(p, name)
        k = len(p) // 2
        kept, column[k] = column[k], value
        assert solver.health() == "the particle state has NaN or infinite values"
        column[k] = kept
        assert solver.health() is None
