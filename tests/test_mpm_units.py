"""DAMPM building blocks: particle location and Q1 basis, seeding, packing, projection."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.mesh import build_discretization
from mpm.grid import ParticleGrid
from mpm.particles import Particles, seed_particles
from mpm.projection import GridProjector, tridiagonal_mass_solve

COMM = MPI.COMM_SELF


@pytest.fixture(scope="module")
def grid():
    disc = build_discretization(COMM, (100.0, 112.0, -3.0, 4.0), (6, 7), {})
    return ParticleGrid(disc)


def _random_particles(grid, n, seed=0):
    rng = np.random.default_rng(seed)
    cell = rng.integers(0, grid.nx * grid.ny, n)
    return cell, rng.random(n), rng.random(n)


def test_basis_is_the_bilinear_q1_basis_of_the_cell(grid):
    cell, xi, eta = _random_particles(grid, 200)
    b = grid.basis(cell, xi, eta)
    x0, y0 = grid.cell_origin(cell)
    x, y = x0 + xi * grid.dx, y0 + eta * grid.dy
    coords = grid.disc.coords[b.nodes]  # (n, 4, 2)
    # nodal interpolation of any bilinear function is exact
    f = lambda X, Y: 2.0 + 0.3 * X - 0.7 * Y + 0.05 * X * Y  # noqa: E731
    values = f(coords[..., 0], coords[..., 1])
    assert np.abs((b.N * values).sum(axis=1) - f(x, y)).max() < 1e-11
    grad = np.einsum("pk,pka->pa", values, b.dN)
    assert np.abs(grad[:, 0] - (0.3 + 0.05 * y)).max() < 1e-11
    assert np.abs(grad[:, 1] - (-0.7 + 0.05 * x)).max() < 1e-11
    assert np.abs(b.N.sum(axis=1) - 1.0).max() < 1e-15


def test_closed_form_basis_equals_basix_tabulation(grid):
    import basix

    cell, xi, eta = _random_particles(grid, 300, seed=3)
    element = basix.create_element(basix.ElementFamily.P, basix.CellType.quadrilateral, 1)
    tab = element.tabulate(1, np.column_stack([xi, eta]))
    b = grid.basis(cell, xi, eta)
    assert np.abs(b.N - tab[0, :, :, 0]).max() < 1e-15
    assert np.abs(b.dN[:, :, 0] * grid.dx - tab[1, :, :, 0]).max() < 1e-14
    assert np.abs(b.dN[:, :, 1] * grid.dy - tab[2, :, :, 0]).max() < 1e-14


def test_move_carries_whole_cells(grid):
    cell = np.array([0, 0, grid.nx + 2])
    i, j, xi, eta = grid.move(cell, np.array([0.5, 0.5, 0.25]), np.array([0.5, 0.5, 0.5]),
                              np.array([2.5 * grid.dx, -grid.dx, 0.0]),
                              np.array([0.0, 0.0, -1.75 * grid.dy]))
    assert list(i) == [3, -1, 2] and list(j) == [0, 0, -1]
    assert np.allclose(xi, [0.0, 0.5, 0.25]) and np.allclose(eta, [0.5, 0.5, 0.75])


def test_seeded_volume_equals_the_lumped_nodal_volume(grid):
    x, y = grid.disc.coords[:, 0], grid.disc.coords[:, 1]
    h = np.maximum(1.0 - ((x - 106) / 4) ** 2 - ((y - 0.5) / 3) ** 2, 0.0)
    for n in (1, 2, 3):
        p = seed_particles(grid, h, 0 * h, 0 * h, n)
        volume = float(np.sum(grid.disc.lumped_mass * h))
        assert abs(p.volume.sum() / volume - 1.0) < 1e-14, n
        assert np.unique(p.id).size == len(p) and p.h.min() > 0.0


def test_pack_unpack_round_trip(grid):
    cell, xi, eta = _random_particles(grid, 5)
    rng = np.random.default_rng(1)
    p = Particles(xi, eta, *rng.random((7, 5)), cell=cell, id=np.arange(5) * 2**40)
    q = Particles.unpack(p.pack())
    for name in ("xi", "eta", "volume", "h", "u", "v", "sxx", "syy", "sxy", "cell", "id"):
        assert np.array_equal(getattr(p, name), getattr(q, name)), name


def test_tridiagonal_mass_solve_matches_a_dense_solve():
    n = 9
    m = (np.diag(np.full(n, 4.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1))
    m[0, 0] = m[-1, -1] = 2.0
    rhs = np.random.default_rng(2).random((3, n))
    x = tridiagonal_mass_solve(rhs)
    assert np.abs(x @ (m / 6.0).T - rhs).max() < 1e-14


def test_projection_is_exact_for_gauss_sampled_fields_and_positive_for_one_particle(grid):
    disc = grid.disc
    proj = GridProjector(disc, grid.cell_nodes)
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    h = 3.0 + np.sin(x) * np.cos(y)
    p = seed_particles(grid, h, 0 * h, 0 * h, 2)
    b = grid.basis(p.cell, p.xi, p.eta)
    sums = np.zeros((x.size, 3))
    np.add.at(sums[:, 0], b.nodes.ravel(), (p.volume[:, None] * b.N).ravel())
    out = proj.project(sums)
    assert np.abs(out[:, 0] - h).max() < 1e-13
    single = np.zeros_like(sums)  # one particle: the consistent projection undershoots
    single[b.nodes[0], 0] = 0.2 * b.N[0]
    out = proj.project(single)
    assert out[:, 0].min() >= 0.0 and proj.iterations > 1
    assert abs(np.sum(proj.lumped_mass * out[:, 0]) - 0.2) < 1e-15
