"""DAMPM building blocks: particle location and Q1 basis, seeding, packing, GIMP, splitting.

The grid projector on its own: tests/test_grid_projection.py.
"""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.mesh import build_discretization
from mpm.gimp import gimp_weights
from mpm.grid import ParticleGrid
from mpm.nodal import NodalGrid, no_faster_than
from mpm.particles import Particles, seed_particles
from mpm.projection import GridProjector
from mpm.split import DomainSplitter
from tests.counting_comm import CountingComm

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


@pytest.mark.parametrize("side", ["open", "wall"])
def test_displace_carries_whole_cells_and_stops_at_the_sides(side):
    g = ParticleGrid(build_discretization(COMM, (100.0, 112.0, -3.0, 4.0), (6, 7),
                                          dict.fromkeys(("left", "right", "bottom", "top"), side)))
    # one move across cells inside, one past the left side, one past the bottom
    cell, xi, eta, out, swap = g.displace(
        np.array([0, 0, g.nx + 2]), np.array([0.5, 0.5, 0.25]), np.array([0.5, 0.5, 0.5]),
        np.array([2.5 * g.dx, -g.dx, 0.0]), np.array([0.0, 0.0, -1.75 * g.dy]))
    assert swap is None
    assert cell[0] == 3 and xi[0] == 0.0 and eta[0] == 0.5
    if side == "open":
        assert list(out) == [False, True, True]
    else:  # put on the wall: the left side's column 0 at ξ = 0, the bottom row at η = 0
        assert not out.any()
        assert cell[1] == 0 and xi[1] == 0.0 and eta[1] == 0.5
        assert cell[2] == 2 and xi[2] == 0.25 and eta[2] == 0.0


def test_seeded_volume_equals_the_lumped_nodal_volume(grid):
    x, y = grid.disc.coords[:, 0], grid.disc.coords[:, 1]
    h = np.maximum(1.0 - ((x - 106) / 4) ** 2 - ((y - 0.5) / 3) ** 2, 0.0)
    for n in (1, 2, 3):
        p = seed_particles(grid, h, 0 * h, 0 * h, n)
        volume = float(np.sum(grid.disc.lumped_mass * h))
        assert abs(p.volume.sum() / volume - 1.0) < 1e-14, n
        assert np.unique(p.id).size == len(p) and p.h.min() > 0.0
        tol = 0.05  # no particle at or below the dry tolerance; the volume left out is below it
        q = seed_particles(grid, h, 0 * h, 0 * h, n, min_depth=tol)
        assert q.h.min() > tol and len(q) < len(p)
        dropped = ~np.isin(p.id, q.id)
        assert p.h[dropped].max() <= tol and np.array_equal(p.h[~dropped], q.h)
        assert 0.0 < volume - q.volume.sum() <= tol * p.area[dropped].sum() * (1 + 1e-14)


def test_pack_unpack_round_trip(grid):
    cell, xi, eta = _random_particles(grid, 5)
    rng = np.random.default_rng(1)
    p = Particles(xi, eta, *rng.random((9, 5)), cell=cell, id=np.arange(5) * 2**40)
    q = Particles.unpack(p.pack())
    for name in ("xi", "eta", "lx", "ly", "volume", "h", "u", "v", "sxx", "syy", "sxy", "cell",
                 "id"):
        assert np.array_equal(getattr(p, name), getattr(q, name)), name


def test_projection_is_exact_for_gauss_sampled_fields_and_positive_for_one_particle(grid):
    disc = grid.disc
    proj = GridProjector(disc.cells, disc.spacing)
    nodal = NodalGrid(disc)
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    h = 3.0 + np.sin(x) * np.cos(y)
    p = seed_particles(grid, h, 0 * h, 0 * h, 2, "gauss")
    nodes, S, _ = _weights(grid, p)
    assert np.array_equal(S, _weights(grid, p, point=True)[1])  # domains inside the cells
    sums = np.zeros((nodal.n_nodes, 3))
    np.add.at(sums[:, 0], nodes.ravel(), (p.volume[:, None] * S).ravel())
    out = proj.project(sums)
    assert np.abs(nodal.to_local(out[:, 0]) - h).max() < 1e-13
    single = np.zeros_like(sums)  # one particle: the consistent projection undershoots
    np.add.at(single[:, 0], nodes[0], 0.2 * S[0])
    out = proj.project(single)
    assert out[:, 0].min() >= 0.0 and proj.limited > 0
    assert abs(np.sum(proj.lumped_mass * out[:, 0]) - 0.2) < 1e-15


def _weights(grid, p, point=False):
    lx, ly = (0 * p.lx, 0 * p.ly) if point else (p.lx, p.ly)
    return gimp_weights(p.cell, p.xi, p.eta, lx, ly, grid.nx, grid.ny, grid.dx, grid.dy)


def _domain_average(grid, p, k, values):
    """Average over particle k's clipped domain of the Q1 interpolant (fine midpoint rule)."""
    x, y = p.positions(grid)
    xmin, xmax, ymin, ymax = grid.xmin, grid.xmax, grid.ymin, grid.ymax
    lo = max(x[k] - p.lx[k], xmin), max(y[k] - p.ly[k], ymin)
    hi = min(x[k] + p.lx[k], xmax), min(y[k] + p.ly[k], ymax)
    m = 400
    sx = lo[0] + (np.arange(m) + 0.5) / m * (hi[0] - lo[0])
    sy = lo[1] + (np.arange(m) + 0.5) / m * (hi[1] - lo[1])
    X, Y = np.meshgrid(sx, sy)
    return values(X, Y).mean()


def test_gimp_weights_average_the_q1_basis_over_the_domain(grid):
    cell, xi, eta = _random_particles(grid, 40, seed=5)
    rng = np.random.default_rng(6)
    n = cell.size
    p = Particles(xi, eta, rng.random(n) * grid.dx / 2, rng.random(n) * grid.dy / 2,
                  *np.ones((7, n)), cell=cell, id=np.arange(n))
    nodes, S, dS = _weights(grid, p)
    assert np.abs(S.sum(axis=1) - 1.0).max() < 1e-14  # partition of unity, clipped domains too
    assert np.abs(dS.sum(axis=1)).max() < 1e-12
    nx = grid.nx + 1
    X0, Y0 = grid.xmin + (nodes % nx) * grid.dx, grid.ymin + (nodes // nx) * grid.dy
    for k in range(n):
        for node in np.unique(nodes[k]):  # the weight is the domain average of the hat function
            x0, y0 = X0[k][nodes[k] == node][0], Y0[k][nodes[k] == node][0]

            def hat(X, Y, x0=x0, y0=y0):
                return (np.maximum(0, 1 - np.abs(X - x0) / grid.dx)
                        * np.maximum(0, 1 - np.abs(Y - y0) / grid.dy))
            weight = S[k][nodes[k] == node].sum()  # slots past the edge repeat a node, weight 0
            assert abs(weight - _domain_average(grid, p, k, hat)) < 1e-5
    f = lambda X, Y: 2.0 + 0.3 * X - 0.7 * Y  # noqa: E731  (linear: S reproduces it)
    x, y = p.positions(grid)
    inside = ((x - p.lx > grid.xmin) & (x + p.lx < grid.xmax) & (y - p.ly > grid.ymin)
              & (y + p.ly < grid.ymax))
    assert np.abs((S * f(X0, Y0)).sum(axis=1) - f(x, y))[inside].max() < 1e-11
    assert np.abs((dS * f(X0, Y0)[..., None]).sum(axis=1) - [0.3, -0.7]).max() < 1e-11


def test_split_halves_the_stretched_particles_and_keeps_everything_else(grid, monkeypatch):
    monkeypatch.setattr(grid, "comm", CountingComm(grid.comm))
    one = np.ones(grid.disc.coords.shape[0])
    p = seed_particles(grid, one, 0 * one, 0 * one, 2)
    n0, v0 = len(p), p.volume.sum()
    splitter = DomainSplitter(grid, 2, int(p.id.max()) + 1)
    p.u[:] = np.arange(n0)
    x0, y0 = p.positions(grid)
    middle = np.flatnonzero((np.abs(x0 - 106.0) < 2.0) & (np.abs(y0 - 0.5) < 2.0))
    wide, tall = middle[:3], middle[5]
    p.lx[wide] *= 4.5  # 1.125 Δx: split twice (four children each)
    p.ly[tall] *= 2.2  # 0.55 Δy: split once
    lx, ly = p.lx.copy(), p.ly.copy()  # split changes p in place
    q = splitter.split(p)
    assert len(q) == n0 + 3 * 3 + 1 and splitter.count == 10
    assert grid.comm.calls == {"allgather": 2}  # one message per pair of passes: (x, y), (x, y)
    assert np.unique(q.id).size == len(q) and np.isin(p.id, q.id).all()
    assert abs(q.volume.sum() - v0) < 1e-14 * v0
    lim_x, lim_y = splitter.limits(q)
    assert (q.lx <= lim_x).all() and (q.ly <= lim_y).all()
    x, y = q.positions(grid)
    for k in (*wide, tall):  # the children tile the parent's domain, centred on it
        kids = q.u == k
        assert abs(np.average(x[kids], weights=q.volume[kids]) - x0[k]) < 1e-12
        assert abs(np.average(y[kids], weights=q.volume[kids]) - y0[k]) < 1e-12
        area = (4 * q.lx[kids] * q.ly[kids]).sum()
        assert abs(area - 4 * lx[k] * ly[k]) < 1e-12


def test_stretch_keeps_the_area_bounds_the_aspect_and_caps_thin_particles(grid):
    one = np.ones(grid.disc.coords.shape[0])
    p = seed_particles(grid, one, 0 * one, 0 * one, 2)
    n = len(p)
    splitter = DomainSplitter(grid, 2, int(p.id.max()) + 1, thin_depth=0.01)
    p.h[: n // 2] = 1e-3  # thin: never wider than the split limit
    lx0, ly0 = p.lx.copy(), p.ly.copy()
    grad = np.zeros((n, 2, 2))
    grad[:, 0, 0], grad[:, 1, 1] = 19.0, -0.9  # x stretched 20x, y squeezed 10x in 1 s
    splitter.stretch(p, 1.0, grad)
    thick = slice(n // 2, None)
    aspect = (p.lx / grid.dx) / (p.ly / grid.dy)  # in cell units
    assert np.abs(aspect[thick] - splitter.max_aspect).max() < 1e-12  # 200 bounded to 4
    assert np.abs(p.lx * p.ly - 2 * lx0 * ly0)[thick].max() < 1e-12 * (lx0 * ly0).max()
    lim_x, lim_y = splitter.limits(p)
    assert (p.lx[: n // 2] <= lim_x[: n // 2]).all()
    assert (p.ly[: n // 2] <= lim_y[: n // 2]).all()
    q = splitter.split(p)
    assert len(q) == n + (n - n // 2)  # only the thick ones split (once, along x)


def test_strain_velocity_is_no_faster_than_the_friction_updated_one():
    """``a |b| / max(|a|, |b|)``: unchanged when not faster, 0 where held, continuous."""
    ax, ay = np.array([3.0, 3.0, 3.0, 0.0, 1e-300]), np.array([4.0, 4.0, 4.0, 0.0, 0.0])
    bx, by = np.array([0.0, 6.0, 3.0, 0.0, 0.0]), np.array([0.0, 8.0, 0.0, 0.0, 0.0])
    x, y = no_faster_than(ax, ay, bx, by)
    assert np.allclose(x, [0.0, 3.0, 1.8, 0.0, 0.0], rtol=1e-15, atol=0.0)
    assert np.allclose(y, [0.0, 4.0, 2.4, 0.0, 0.0], rtol=1e-15, atol=0.0)
    assert x[1] == 3.0 and y[1] == 4.0 and x[0] == y[0] == 0.0  # exactly kept, exactly held
    eps = np.array([1e-14, -1e-14])  # a round-off change of |b| moves the result by round-off
    x1, _ = no_faster_than(np.full(2, 3.0), np.full(2, 4.0), 5.0 + eps, np.zeros(2))
    assert np.abs(x1 - 3.0).max() <= 1e-14


def test_apic_round_trip_keeps_a_linear_velocity_field_exactly(grid):
    """APIC (Jiang et al. 2015): G2P then P2G returns any affine nodal velocity exactly.

    The particles take ``v_p = Σ v_i S_ip`` and ``C_p = Σ v_i ∇S_ip^T``; the grid gets
    ``Σ m_p S_ip (v_p + C_p (x_i - x̄_p)) / M_i``. For ``v = A x + b`` every particle's term
    is ``A x_i + b`` (the GIMP weights reproduce linear functions), so the nodal velocity
    comes back at every node with mass; the PIC round trip (``C_p = 0``) smooths it.
    """
    from fem_runout.exact_sum import extractors
    from mpm.gimp import gimp_basis
    from mpm.kernels import g2p_flip, g2p_gradient, p2g_momentum

    cell, xi, eta = _random_particles(grid, 300, seed=11)
    rng = np.random.default_rng(12)
    n = cell.size
    lx, ly = rng.random(n) * grid.dx / 2, rng.random(n) * grid.dy / 2
    b = gimp_basis(cell, xi, eta, lx, ly, grid.nx, grid.ny, grid.dx, grid.dy)
    X = grid.xmin + np.tile(np.arange(grid.nx + 1), grid.ny + 1) * grid.dx
    Y = grid.ymin + np.repeat(np.arange(grid.ny + 1), grid.nx + 1) * grid.dy
    A, b0 = np.array([[0.3, -1.1], [0.7, 0.2]]), np.array([2.0, -1.5])
    vx, vy = A[0, 0] * X + A[0, 1] * Y + b0[0], A[1, 0] * X + A[1, 1] * Y + b0[1]
    zero = np.zeros_like(X)
    u, v = g2p_flip(b.arrays, vx, vy, zero, zero, zero, np.zeros(n), np.zeros(n), 0.0)
    c = g2p_gradient(b.arrays, vx, vy)
    assert np.abs(c - A).max() < 1e-12
    mass = rng.uniform(0.5, 2.0, n)
    box = np.array([0, 0, grid.ny + 1, grid.nx + 1])
    ext = extractors([1e3, 1e3], n, COMM)
    for affine, exact in ((c.reshape(n, 4).T.copy(), True), (np.zeros((4, n)), False)):
        mom = p2g_momentum(b.arrays, mass, u, v, affine, box, ext).sum(axis=2)
        weight = p2g_momentum(b.arrays, mass, np.ones(n), np.zeros(n), np.zeros((4, n)), box,
                              ext).sum(axis=2)[:, 0]
        has = weight > 1e-3 * mass.max()
        error = max(np.abs(mom[has, 0] / weight[has] - vx[has]).max(),
                    np.abs(mom[has, 1] / weight[has] - vy[has]).max())
        assert (error < 1e-11) if exact else (error > 1e-2)


def test_apic_split_gives_each_half_the_affine_velocity_at_its_centre(grid):
    one = np.ones(grid.disc.coords.shape[0])
    p = seed_particles(grid, one, 0 * one, 0 * one, 2).with_fields(affine=True, quad=False)
    splitter = DomainSplitter(grid, 2, int(p.id.max()) + 1)
    p.u[:], p.v[:] = 1.0, -2.0
    p.cxx[:], p.cxy[:], p.cyx[:], p.cyy[:] = 0.5, -0.25, 0.125, 2.0
    x0, y0 = p.positions(grid)
    k = int(np.argmin((x0 - 106.0) ** 2 + (y0 - 0.5) ** 2))
    p.lx[k] *= 2.2  # split once along x
    p.ly[k] *= 2.2  # and each half once along y
    momentum = (p.volume * p.u).sum(), (p.volume * p.v).sum()
    q = splitter.split(p)
    x, y = q.positions(grid)
    kids = np.isin(q.id, [p.id[k]]) | (q.id >= splitter.next_id - splitter.count)
    assert kids.sum() == 4
    assert abs((q.volume * q.u).sum() - momentum[0]) < 1e-12 * abs(momentum[0])
    assert abs((q.volume * q.v).sum() - momentum[1]) < 1e-12 * abs(momentum[1])
    du, dv = q.u[kids] - 1.0, q.v[kids] + 2.0
    dx, dy = x[kids] - x0[k], y[kids] - y0[k]
    assert np.abs(du - (0.5 * dx - 0.25 * dy)).max() < 1e-12
    assert np.abs(dv - (0.125 * dx + 2.0 * dy)).max() < 1e-12


def test_legacy_checkpoint_rows_without_the_affine_velocity_unpack():
    rng = np.random.default_rng(3)
    p = Particles(*rng.random((11, 4)), cell=np.arange(4), id=np.arange(4) * 7)
    rows = p.pack()
    legacy = np.concatenate([rows[:, :11], rows[:, -2:]], axis=1)  # 13 columns (session 12)
    q = Particles.unpack(legacy)
    assert np.array_equal(q.pack(), rows) and not q.cxx.any()


def test_optional_particle_groups_are_carried_only_when_asked():
    rng = np.random.default_rng(5)
    p = Particles(*rng.random((11, 6)), cell=np.arange(6), id=np.arange(6) * 3)
    assert not p.has_affine and not p.has_quad
    assert not p.affine().any() and p.affine().shape == (4, 6) and p.quad().shape == (6, 8)
    rows = p.pack()
    assert rows.shape == (6, 25) and not rows[:, 11:23].any()
    q = Particles.unpack(rows, affine=False, quad=False)
    assert not q.has_affine and not q.has_quad and np.array_equal(q.pack(), rows)
    both = Particles.concatenate([q, q.select(np.array([1, 4]))])
    assert len(both) == 8 and not both.has_quad and np.array_equal(both.id[6:], [3, 12])
    snap, _ = both.copy_into(None)
    assert np.array_equal(snap.pack(), both.pack()) and snap.cxx is None
    full = q.with_fields(affine=True, quad=True)
    assert full.has_affine and full.has_quad and not full.q3y.any()
    with pytest.raises(ValueError, match="cxx"):
        q.select_and_append(np.ones(6, dtype=bool), full)
