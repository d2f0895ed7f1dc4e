"""DAMPM's quadrilateral particle domains on gmsh meshes (issue 17, mpm/mesh_clip.py).

The domains are physical quadrilaterals cut by the cells, so the particle quadrature does not
depend on which cell a particle is in: a smooth depth field carried by particles translated
across an irregular mesh projects with the grid's accuracy (before, a rectangle in the cell's
reference coordinates changed shape from cell to cell and the error stopped converging).
"""

import math

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.bench.meshes import BOWL, outline_overrides
from fem_runout.config import load_case
from fem_runout.methods import get
from fem_runout.references import thacker as ref
from mpm.mesh_clip import clip, convex_parts, polygon_area
from mpm.mesh_grid import MeshParticleGrid, crossing_lengths
from mpm.mesh_locate import inverse_anchor, invert_near, map_point
from mpm.mesh_weights import domain_basis, domain_scratch
from mpm.particles import Particles
from mpm.quad_split import RESPLIT, QuadSplitter
from mpm.weight_reuse import PreviousWeights
from tests.quad_helpers import distorted_rectangle


def _grid(amp: float) -> MeshParticleGrid:
    """The particle grid of a 12 × 9 rectangle with nodes jittered by ``amp`` cells."""
    sides = {"left": "open", "right": "wall", "bottom": "wall", "top": "open"}
    disc = distorted_rectangle(MPI.COMM_SELF, (0.0, 12.0, 0.0, 9.0), (12, 9), sides, amp, 0)
    return MeshParticleGrid(disc)


def test_clip_gives_the_overlap_of_two_squares_and_the_parts_of_a_reflex_cell():
    px, py = np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0])
    cx, cy = np.array([0.25, 2.0, 2.0, 0.25]), np.array([0.5, 0.5, 3.0, 3.0])
    n, cut = clip(px, py, 4, cx, cy, 4, np.empty(16), np.empty(16))
    assert cut and abs(polygon_area(px, py, n) - 0.75 * 0.5) <= 1e-15
    px, py = np.array([0.5, 0.6, 0.6, 0.5]), np.array([0.6, 0.6, 0.7, 0.7])
    assert not clip(px, py, 4, cx, cy, 4, np.empty(16), np.empty(16))[1]  # inside: uncut
    # a dart: the reflex corner (1, 0.4) splits it into two triangles of the same total area
    dx, dy = np.array([0.0, 2.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.4, 2.0])
    tx, ty, tn = np.empty((2, 4)), np.empty((2, 4)), np.empty(2, np.int64)
    parts = convex_parts(dx, dy, tx, ty, tn)
    areas = [polygon_area(tx[k], ty[k], tn[k]) for k in range(parts)]
    assert parts == 2 and min(areas) > 0.0
    assert abs(sum(areas) - polygon_area(dx, dy, 4)) <= 1e-15


def _translated_projection_error(n: int, shift: float) -> float:
    """L1 error of the projected depth of Thacker's initial depth moved by ``shift`` cells."""
    over = [*outline_overrides(BOWL, ref.L / n), "method=mpm"]  # gmsh's mesh of the disc
    s = get("mpm").build(load_case(ref.case_dict(n), over), MPI.COMM_SELF)
    d = shift * ref.L / n
    p = s.particles
    p.cell, p.xi, p.eta, _, _ = s.grid.displace(p.cell, p.xi, p.eta, np.full(len(p), d),
                                                np.full(len(p), 0.3 * d))
    x, y = p.positions(s.grid)
    area = p.area.copy()
    p.h = np.maximum(ref.depth(x - d, y - 0.3 * d, 0.0), 1e-12)  # the same field, carried
    p.volume = area * p.h
    s._refresh()
    own = s.disc.n_owned_nodes
    xy = s.disc.coords[:own, :2]
    h = s._h[s.nodal.node_index[:own]]
    exact = ref.depth(xy[:, 0] - d, xy[:, 1] - 0.3 * d, 0.0)
    inner = np.hypot(xy[:, 0] - d - ref.L / 2 - ref.ETA, xy[:, 1] - 0.3 * d - ref.L / 2) <= (
        0.8 * ref.A)
    return float(np.sum(s.lumped_mass[:own][inner] * np.abs(h - exact)[inner]))


def test_points_are_inverted_from_an_anchor_to_round_off_in_distorted_cells():
    """The weights' quadrature points are inverted in closed form from a known point of the
    cell (the particle, or the cell's centre): exact to round-off in strongly distorted convex
    cells (trapezoids, kites, a 30 % jittered mesh), from any anchor to any point."""
    rng = np.random.default_rng(7)
    corners = [np.array([[0, 0], [4, 0], [0, 2], [3, 2.5]]),  # trapezoid-like
               np.array([[0, 0], [2, -1], [-1, 2], [3, 3]]),  # kite
               np.array([[1e5, 2e5], [1e5 + 5, 2e5 + 0.5], [1e5 - 1, 2e5 + 4],
                         [1e5 + 6, 2e5 + 6]])]  # far from the origin, as on a DEM
    g = _grid(0.3)
    for k in range(0, g.n_cells, 7):
        corners.append(g.coords[g.corners[k]])
    worst = 0.0
    for c in corners:
        c = np.asarray(c, dtype=float)
        geo = np.array([[*(c[1] - c[0]), *(c[2] - c[0]), *(c[0] - c[1] - c[2] + c[3])]])
        for a0, b0 in [(0.5, 0.5), *rng.uniform(0.0, 1.0, (3, 2))]:
            anchor = inverse_anchor(geo, 0, a0, b0)
            x0, y0 = map_point(geo, 0, a0, b0)
            for a, b in rng.uniform(0.0, 1.0, (40, 2)):
                tx, ty = map_point(geo, 0, a, b)
                got = invert_near(geo, 0, anchor, tx - x0, ty - y0, tx, ty)
                worst = max(worst, abs(got[0] - a), abs(got[1] - b))
    assert worst < 1e-12, worst


def test_a_translated_smooth_layer_projects_at_second_order_on_gmsh_cells():
    """Particles moved by half a cell on gmsh's meshes of Thacker's disc: the projection of
    their volumes converges at second order (measured 2.06 and 1.64; the former domains, a
    rectangle in the reference coordinates of the particle's cell, gave 0.41 and 0.36)."""
    errors = [_translated_projection_error(n, 0.5) for n in (25, 50, 100)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert min(orders) > 1.3, (errors, orders)


def test_seeded_domains_tile_the_cells_and_sit_at_their_centroids():
    """The sub-cells of a jittered mesh: areas summing to the cells', corners' mean at the
    particle only for parallelograms, the first moment of the weights zero (centroid)."""
    g = _grid(0.3)
    cell = np.repeat(np.arange(g.n_cells), 4)
    xi0, eta0 = np.tile([0.25, 0.75, 0.25, 0.75], g.n_cells), np.tile([0.25, 0.25, 0.75, 0.75],
                                                                      g.n_cells)
    xi, eta, area, quad = g.seed_domains(cell, xi0, eta0, 2)
    cells = g.centre_jacobians()
    cell_area = np.abs(cells[:, 0] * cells[:, 3] - cells[:, 1] * cells[:, 2])
    assert np.allclose(np.bincount(cell, area), cell_area, rtol=1e-13)
    p = Particles(xi, eta, 0 * xi, 0 * xi, area, np.ones_like(xi), 0 * xi, 0 * xi, 0 * xi,
                  0 * xi, 0 * xi, cell=cell, id=np.arange(cell.size))
    p.set_quad(quad)
    off, nodes, S, dS, rel = g.particle_basis(p).arrays
    rows = np.repeat(np.arange(cell.size), np.diff(off))
    moment = np.stack([np.bincount(rows, S * rel[:, k]) for k in range(2)], axis=1)
    assert np.abs(moment).max() <= 1e-13 * np.abs(quad).max()
    # every node's weights add up to the area its sub-cells hold of its hat function's support
    assert abs(np.sum(S * area[rows]) - cell_area.sum()) <= 1e-12 * cell_area.sum()


def _moved_domains(g: MeshParticleGrid, rng, reach: float) -> tuple[np.ndarray, ...]:
    """Four seeded domains per cell, moved by up to ``reach`` cells: ``(cell, ξ, η, A, quad)``."""
    cell = np.repeat(np.arange(g.n_cells), 4)
    xi0, eta0 = np.tile([0.25, 0.75, 0.25, 0.75], g.n_cells), np.tile([0.25, 0.25, 0.75, 0.75],
                                                                      g.n_cells)
    xi, eta, area, quad = g.seed_domains(cell, xi0, eta0, 2)
    step = rng.uniform(-reach, reach, (cell.size, 2))
    cell, xi, eta, _, _ = g.displace(cell, xi, eta, step[:, 0], step[:, 1])
    return cell, xi, eta, area, quad


def test_cost_estimate_follows_the_cells_a_moved_domain_reaches():
    """The load balance's per-particle cost on a gmsh mesh (3 inside the cell, 6 across a
    side, 9 around a vertex, 2 at rest) against the entries the weights give: a domain called
    inside has exactly its cell's four nodes, and the entries grow with the estimate (on
    avaKot's corridor it named 6 entries for a side and 8-9 for a vertex for 94 % of the
    particles); a particle at rest costs less than any moving one (its weights are copied)."""
    g = _grid(0.3)
    cell, xi, eta, area, quad = _moved_domains(g, np.random.default_rng(3), 0.3)
    u = np.where(np.arange(cell.size) % 5 == 0, 0.0, 1.0)  # every fifth particle at rest
    p = Particles(xi, eta, 0 * xi, 0 * xi, area, np.ones_like(xi), u, 0 * xi, 0 * xi,
                  0 * xi, 0 * xi, cell=cell, id=np.arange(cell.size))
    p.set_quad(quad)
    cost = g.balance_weights(p)
    entries = np.diff(g.particle_basis(p).arrays[0])
    assert np.array_equal(cost == 2, u == 0.0)
    moving = cost[u > 0.0]
    assert set(np.unique(moving)) <= {3, 6, 9} and (moving == 3).sum() > 0
    assert (moving == 9).sum() > 0 and (entries[cost == 3] == 4).all()
    means = [entries[cost == c].mean() for c in (3, 6, 9)]
    assert means[0] < means[1] < means[2], means  # more cells reached, more cost


def test_the_weights_do_not_depend_on_what_the_scratch_held():
    """The weights' loop reuses its scratch from step to step (kept by the grid): moved domains
    across a jittered mesh give the same bits with fresh scratch and with scratch full of
    garbage."""
    g = _grid(0.3)
    rng = np.random.default_rng(5)
    cell, xi, eta, _, quad = _moved_domains(g, rng, 0.4)
    quad = quad * rng.uniform(0.8, 1.6, (quad.shape[0], 1))  # some domains reach further

    def weights(scratch):
        size = 40 * cell.size
        out = (np.empty(cell.size + 1, np.int64), np.empty(size, np.int64), np.empty(size),
               np.empty((size, 2)), np.empty((size, 2)))
        args = (g.geo, g.origin, g.corners, g.neighbour, cell, xi, eta, quad, *out)
        used = domain_basis(*args, scratch=scratch)
        return [out[0]] + [a[:used] for a in out[1:]]

    fresh = weights(None)
    junk = domain_scratch()
    for a in junk:
        a[...] = rng.integers(0, 2, a.shape) if a.dtype != float else rng.normal(size=a.shape)
    for got in (weights(junk), weights(junk)):
        assert all(np.array_equal(a, b) for a, b in zip(fresh, got, strict=True))
    assert np.diff(fresh[0]).max() > 4  # domains across sides and vertices were visited


def test_quad_split_conserves_volume_and_tiles_the_parent():
    """Whole cells as domains (twice the limit each way): four children each, the volume
    exact (``V_a`` and ``V - V_a``), the children's domains covering the parent's area with
    the parent's centroid."""
    g = _grid(0.3)
    cell = np.arange(20, 40)
    half = np.full(cell.size, 0.5)
    xi, eta, area, quad = g.seed_domains(cell, half, half, 1)
    rng = np.random.default_rng(4)
    vol = area * rng.uniform(0.5, 2.0, cell.size)
    p = Particles(xi, eta, 0 * xi, 0 * xi, vol.copy(), vol / area, 0 * xi, 0 * xi, 0 * xi, 0 * xi,
                  0 * xi, cell=cell, id=np.arange(cell.size))
    p.set_quad(quad)
    x0, y0 = p.positions(g)
    first = (math.fsum(area * x0), math.fsum(area * y0))
    splitter = QuadSplitter(g, 3, cell.size)  # limit 1/3 of a cell: one cut each way
    q = splitter.split(p)
    assert len(q) == 4 * cell.size and splitter.count == 3 * cell.size
    assert math.fsum(q.volume) == math.fsum(vol)
    qq = q.quad()
    areas = np.array([polygon_area(qq[i, 0::2], qq[i, 1::2], 4) for i in range(len(q))])
    assert abs(math.fsum(areas) - math.fsum(area)) <= 1e-12 * math.fsum(area)
    x, y = q.positions(g)
    moved = (math.fsum(areas * x), math.fsum(areas * y))
    assert max(abs(a - b) for a, b in zip(moved, first, strict=True)) <= 1e-11 * first[0]
    assert np.all(splitter.widths(q) <= 1.0 / 3.0)


def test_a_pair_of_cuts_flags_only_domains_beyond_the_resplit_bound():
    """After a step's pair of cuts a domain is cut again at once (a collective and a second
    evaluation of the weights) only beyond RESPLIT limits; a half a little over the limit in
    its cell's units (the cells are not parallelograms) waits for the next step's pair."""
    g = _grid(0.3)
    cell = np.arange(g.n_cells)
    half = np.full(cell.size, 0.5)

    def whole_cells() -> Particles:
        xi, eta, area, quad = g.seed_domains(cell, half, half, 1)
        p = Particles(xi, eta, 0 * xi, 0 * xi, area.copy(), 1.0 + 0 * xi, 0 * xi, 0 * xi,
                      0 * xi, 0 * xi, 0 * xi, cell=cell, id=np.arange(cell.size))
        p.set_quad(quad)
        return p

    four = QuadSplitter(g, 4, cell.size)  # limit 1/4: whole cells are 2 limits each way
    q, pending = four.split_pair(whole_cells())
    ratio = four.widths(q) * 4
    assert len(q) == 4 * cell.size and not pending.wide
    assert 1.0 < ratio.max() <= RESPLIT  # some halves over the limit: cut at the next step
    ten = QuadSplitter(g, 10, cell.size)  # 5 limits: one pair leaves 2.5, beyond the bound
    q, pending = ten.split_pair(whole_cells())
    assert pending.wide and (ten.widths(q) * 10).max() > RESPLIT
    q = ten.split(whole_cells())
    assert len(q) == 16 * cell.size and (ten.widths(q) * 10).max() <= RESPLIT
    assert math.fsum(q.volume) == math.fsum(whole_cells().volume)


def test_crossing_lengths_are_the_grids_cell_size_on_squares_and_shorter_on_skewed_cells():
    """DAMPM's CFL length on a mesh: sqrt(2)|K|/d_max, Δx on squares; on a rectangle a × b
    sqrt(2)/sqrt(1/a² + 1/b²) (the ratio of the explicit wave steps); on a skewed
    parallelogram (one long diagonal) less than its shortest edge; for a domain reaching
    beyond its cell the smallest over the cell and the cells across its sides, for one inside
    its cell (four weights) the cell's own."""
    coords = np.array([[0, 0], [2, 0], [0, 2], [2, 2], [5, 0], [5, 2],
                       [10, 0], [12, 0], [11.8, 0.6], [13.8, 0.6]])
    corners = np.array([[0, 1, 2, 3], [1, 4, 3, 5], [6, 7, 8, 9]])
    alone, same = crossing_lengths(coords, corners, np.full((3, 4), -1))
    assert same.tolist() == alone.tolist()
    assert alone[0] == pytest.approx(2.0, rel=1e-15)
    assert alone[1] == pytest.approx(math.sqrt(2.0) / math.hypot(1 / 3, 1 / 2), rel=1e-15)
    # edges 2 and 1.90, height 0.6, diagonals 3.85 and 0.63
    assert alone[2] == pytest.approx(math.sqrt(2.0) * 1.2 / math.hypot(3.8, 0.6), rel=1e-15)
    assert alone[2] < 0.6 < math.hypot(1.8, 0.6)
    own, row = crossing_lengths(coords, corners, np.array([[-1, 1, -1, -1], [0, 2, -1, -1],
                                                           [1, -1, -1, -1]]))
    assert own.tolist() == alone.tolist()
    assert row.tolist() == [min(alone[0], alone[1]), alone.min(), min(alone[1], alone[2])]
    g = _grid(0.0)  # the 12 x 9 grid of unit squares
    np.testing.assert_allclose(g.local_size, 1.0, rtol=1e-14, atol=0)
    g = _grid(0.3)
    k = int(np.flatnonzero((g.local_size < g.cell_size) & (g.neighbour >= 0).all(axis=1))[0])
    cell = np.array([k, k])
    xi, eta, area, quad = g.seed_domains(cell, np.array([0.5, 0.5]), np.array([0.5, 0.5]), 4)
    p = Particles(xi, eta, 0 * xi, 0 * xi, area, 1.0 + 0 * xi, 0 * xi, 0 * xi, 0 * xi, 0 * xi,
                  0 * xi, cell=cell, id=np.arange(2))
    quad[1] *= 6.0  # 1.5 cells wide: reaches the neighbours
    p.set_quad(quad)
    sizes = g.crossing_sizes(p, g.particle_basis(p))
    assert sizes.tolist() == [g.cell_size[k], g.local_size[k]]


def test_stretch_maps_the_corner_arrays_in_place_by_the_velocity_gradient():
    """The splitter deforms the particles' own corner arrays (no (n, 8) copy): every offset
    is mapped by I + dt grad v, so each domain's area changes by det(I + dt grad v) (within
    the aspect bound), and quad_at / set_quad_at read and write rows in place."""
    g = _grid(0.3)
    cell = np.arange(20, 40)
    quarter = np.full(cell.size, 0.5)
    xi, eta, area, quad = g.seed_domains(cell, quarter, quarter, 4)
    p = Particles(xi, eta, 0 * xi, 0 * xi, area.copy(), 1.0 + 0 * xi, 0 * xi, 0 * xi, 0 * xi,
                  0 * xi, 0 * xi, cell=cell, id=np.arange(cell.size))
    p.set_quad(quad)
    column = p.q1x
    grad = np.tile(np.array([[0.2, 0.1], [-0.05, 0.1]]), (cell.size, 1, 1))
    dt = 0.5
    QuadSplitter(g, 2, cell.size).stretch(p, dt, grad)
    assert p.q1x is column  # changed in place
    m = np.eye(2) + dt * grad[0]
    q = p.quad()
    assert np.allclose(q[:, 0::2], m[0, 0] * quad[:, 0::2] + m[0, 1] * quad[:, 1::2],
                       rtol=0, atol=1e-14)
    areas = np.array([polygon_area(q[i, 0::2], q[i, 1::2], 4) for i in range(len(p))])
    assert np.allclose(areas, np.linalg.det(m) * area, rtol=1e-13, atol=0)
    rows = np.array([3, 7])
    new = p.quad_at(rows) + 1.0
    p.set_quad_at(rows, new)
    assert np.array_equal(p.quad()[rows], new) and p.q1x is column
    assert np.array_equal(np.delete(p.quad(), rows, axis=0), np.delete(q, rows, axis=0))


def _particles(cell, xi, eta, area, quad, ids) -> Particles:
    """Particles at rest with the given domains and ids."""
    z = 0 * xi
    p = Particles(xi, eta, z, z, area, np.ones_like(xi), z, z, z, z, z, cell=cell, id=ids)
    p.set_quad(quad)
    return p


def test_particles_at_rest_get_the_last_steps_weights_with_the_bits_of_a_computation():
    """The grid copies the last call's weights for a particle whose cell, (ξ, η) and domain
    have the same bits (mpm/weight_reuse.py): after particles left (the others shift down),
    a third of the rest moved and new ones arrived at the end, the weights are those of a
    grid computing every particle; poisoned last-call weights show that the particles at
    rest, and only they, were copied."""
    g, fresh_grid = _grid(0.3), _grid(0.3)
    rng = np.random.default_rng(11)
    cell, xi, eta, area, quad = _moved_domains(g, rng, 0.4)
    n = cell.size
    first = _particles(cell, xi, eta, area, quad, np.arange(n))
    keep = np.arange(n) % 7 != 3  # particles that left
    moved = keep & (rng.uniform(size=n) < 0.33)
    xi2 = np.where(moved, np.where(xi < 0.5, xi + 0.01, xi - 0.01), xi)  # moved in its cell
    new = rng.choice(n, 40, replace=False)  # arrivals: new ids at the end
    second = _particles(np.concatenate([cell[keep], cell[new]]),
                        np.concatenate([xi2[keep], xi[new]]), np.concatenate([eta[keep], eta[new]]),
                        np.concatenate([area[keep], area[new]]),
                        np.concatenate([quad[keep], quad[new]]),
                        np.concatenate([np.arange(n)[keep], n + np.arange(40)]))
    g.particle_basis(first)
    got = g.particle_basis(second).arrays
    want = fresh_grid.particle_basis(second).arrays
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    # the same with the first call's weights poisoned: NaN exactly for the particles at rest
    previous = PreviousWeights()
    size = 40 * n
    bufs = [(np.empty(size + 1, np.int64), np.empty(size, np.int64), np.empty(size),
             np.empty((size, 2)), np.empty((size, 2))) for _ in range(2)]
    for k, (p, out) in enumerate(zip((first, second), bufs, strict=True)):
        used = domain_basis(g.geo, g.origin, g.corners, g.neighbour, p.cell, p.xi, p.eta,
                            p.quad(), *out, previous=previous, ids=p.id)
        previous.keep(len(p), *out)
        if k == 0:
            out[2][:used] = np.nan
    off = bufs[1][0]
    copied = np.array([np.isnan(bufs[1][2][off[k]]) for k in range(len(second))])
    at_rest = np.concatenate([~moved[keep], np.zeros(40, bool)])
    assert np.array_equal(copied, at_rest) and at_rest.sum() > n // 2
