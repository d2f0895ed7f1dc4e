"""Both methods on unstructured quad meshes: the same bits on 1, 2 and 3 ranks (issue 17)."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.physics.slope import slope_geometry
from tests.quad_helpers import distorted_rectangle, on_mesh
from tests.tg2_helpers import assert_same_on_ranks, case

WORLD = MPI.COMM_WORLD


METHODS = ("tg2", "mpm")


@pytest.mark.parametrize("method", METHODS)
def test_lake_at_rest_is_exact_on_a_distorted_mesh_in_parallel(method):
    """To t = 0.25 s: the lake is a fixed point (momenta exactly 0, the same depth error at
    0.25 and 1 s on 2 ranks: 0 for TG2-PC, 8.0e-14 for DAMPM); ``tests/test_quadmesh.py`` and
    ``tests/test_quadmesh_dampm.py`` run the seed's whole second on one rank."""
    with on_mesh(0.3):
        r = run(case("lake_at_rest", f"method={method}", "time.end=0.25"), write=False,
                comm=WORLD)
    if WORLD.rank == 0:
        wet = r.h > 1e-6
        assert np.abs(r.h + r.z - 10.0)[wet].max() <= 1e-12
        assert max(np.abs(r.hu).max(), np.abs(r.hv).max()) <= 1e-12


@pytest.mark.parametrize("method", METHODS)
def test_jittered_mesh_same_on_any_rank_count(method):
    """A dam break down a slope on randomly jittered cells, open and wall sides."""
    with on_mesh(0.3):
        assert_same_on_ranks(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                                  "output.every=1.0", f"method={method}"), WORLD, 0.0)


def test_bent_mesh_closed_box_same_on_any_rank_count():
    """The hemisphere collapse in a walled box of smoothly bent cells, Voellmy friction."""
    with on_mesh(1.0, None):
        assert_same_on_ranks(case("hemisphere", "domain.extent=[15,35,15,35]",
                                  "domain.cells=[30,30]", "domain.boundary=wall",
                                  "time.end=2.0", "output.every=1.0",
                                  "material.friction={law: voellmy, phi_deg: 26, xi: 500}"),
                             WORLD, 0.0)


@pytest.mark.parametrize("method", METHODS)
def test_gmsh_outline_mesh_same_on_any_rank_count(method):
    """The hemisphere on a gmsh mesh of a disc (irregular nodes; DOLFINx's partition)."""
    theta = np.linspace(0.0, 2 * np.pi, 65)[:-1]
    outline = [[float(round(25 + 12 * np.cos(t), 6)), float(round(25 + 12 * np.sin(t), 6))]
               for t in theta]
    assert_same_on_ranks(case("hemisphere", "domain.extent=null", "domain.cells=null",
                              f"domain.outline={outline}", "domain.cell_size=0.5",
                              "domain.boundary=wall", "time.end=1.0", "output.every=1.0",
                              f"method={method}"), WORLD, 0.0)


@pytest.mark.parametrize("method", METHODS)
def test_users_msh_file_same_on_any_rank_count(method):
    """The curved channel's .msh (walls, Manning friction) across the partition."""
    assert_same_on_ranks(case("curved_channel", "time.end=10", "output.every=10",
                              f"method={method}"), WORLD, 0.0)


class _Sent:
    """Runner callback adding up the particles this rank sent to others."""

    def __init__(self) -> None:
        self.sent = 0
        self.moves = 0  # steps at which this rank sent particles

    def start(self, solver, info) -> None:
        """Nothing at start."""

    def step(self, solver, info) -> None:
        """Count the step's migrations."""
        self.sent += solver.sent
        self.moves += solver.sent > 0

    def output(self, solver, info) -> None:
        """Nothing at outputs."""

    def finish(self, solver, info) -> None:
        """Nothing at the end."""


def test_particles_cross_ranks_on_an_unstructured_partition():
    """DAMPM's dam break down a slope on jittered cells: particles move between the ranks'
    strips as the flow runs down, and the result has the serial bits (above)."""
    counter = _Sent()
    with on_mesh(0.3):
        run(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                 "output.every=1.0", "method=mpm"), write=False, comm=WORLD,
            callbacks=[counter])
    sent = WORLD.allreduce(counter.sent)
    moves = WORLD.allreduce(counter.moves)
    if WORLD.size > 1:  # rebalanced every REBALANCE_EVERY steps: several times in 3 s
        assert moves >= 4 and sent >= 20


def test_bed_curvature_on_a_jittered_mesh_has_the_bits_of_one_rank():
    """The recovered Hessian (fem_runout.physics.recovery) does not depend on the partition.

    Nor does the Hessian of the bed smoothed over ``model.curvature_scale``
    (fem_runout.physics.bed_filter).
    """
    sides = {s: "open" for s in ("left", "right", "bottom", "top")}
    parts = []
    for comm in (WORLD, MPI.COMM_SELF):
        disc = distorted_rectangle(comm, (0.0, 100.0, 0.0, 80.0), (20, 16), sides, 0.25, 3)
        x, y = disc.coords[:, 0], disc.coords[:, 1]
        z = 0.002 * x * x + 0.003 * x * y - 0.001 * y * y + np.sin(x / 9.0) * np.cos(y / 7.0)
        geometry = slope_geometry(disc, z, 9.81, True)
        smooth = slope_geometry(disc, z, 9.81, True, 10.0)
        order = np.lexsort((y, x))
        parts.append((disc.coords[order, :2], geometry.hess[order], geometry.grad[order],
                      smooth.hess[order]))
    (xw, hw, gw, sw), (xs, hs, gs, ss) = parts
    at = np.searchsorted(xs[:, 0] * 1e6 + xs[:, 1], xw[:, 0] * 1e6 + xw[:, 1])
    np.testing.assert_array_equal(xs[at], xw)
    np.testing.assert_array_equal(hs[at], hw)  # the same bits
    np.testing.assert_array_equal(gs[at], gw)
    np.testing.assert_array_equal(ss[at], sw)
    assert np.abs(sw - hw).max() > 1e-3  # (the smoothing did change it)
