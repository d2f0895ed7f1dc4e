"""MeshProjector: Q1 projection (lumped / consistent / FCT) on unstructured quad meshes."""

import numpy as np
import pytest

from mpm.mesh_projection import MeshProjector
from mpm.projection import GridProjector


def _mesh(nx, ny, dx=1.0, dy=1.0, jitter=0.0, seed=0):
    """Structured nx × ny grid (node j (nx + 1) + i), nodes moved by up to jitter × cell."""
    jj, ii = np.meshgrid(np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    coords = np.stack([ii.ravel() * dx, jj.ravel() * dy], axis=1).astype(float)
    if jitter:
        rng = np.random.default_rng(seed)
        radius = jitter * rng.uniform(0.0, 1.0, coords.shape[0])
        angle = rng.uniform(0.0, 2.0 * np.pi, coords.shape[0])
        coords += np.stack([radius * np.cos(angle) * dx, radius * np.sin(angle) * dy], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    base = (j * (nx + 1) + i).ravel()
    cells = np.stack([base, base + 1, base + nx + 1, base + nx + 2], axis=1).astype(np.int64)
    return cells, coords


def _tri_quad_mesh(nx, ny, d, seed):
    """Jittered triangulated grid, each triangle cut into 3 quads: valences 3, 4 and 6."""
    _, tri_nodes = _mesh(nx, ny, d, d, jitter=0.25, seed=seed)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    v = (j * (nx + 1) + i).ravel()
    tris = np.concatenate([np.stack([v, v + 1, v + nx + 2], 1),
                           np.stack([v, v + nx + 2, v + nx + 1], 1)])
    edges = np.sort(np.stack([tris, np.roll(tris, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    mids = len(tri_nodes) + inv.reshape(-1, 3)  # mid of edge (k, k + 1)
    cent = len(tri_nodes) + len(uniq) + np.arange(len(tris))
    coords = np.concatenate([tri_nodes, tri_nodes[uniq].mean(axis=1), tri_nodes[tris].mean(axis=1)])
    cells = [np.stack([tris[:, k], mids[:, k], mids[:, k - 1], cent], 1) for k in range(3)]
    return np.concatenate(cells).astype(np.int64), coords


_GAUSS = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])


def _mass_matrix(cells, coords):
    """Dense consistent Q1 mass matrix by 2 × 2 Gauss (exact for bilinear maps)."""
    n = coords.shape[0]
    mc = np.zeros((n, n))
    xc = coords[cells]  # (nc, 4, 2), corners (0,0), (1,0), (0,1), (1,1)
    for s in _GAUSS:
        for t in _GAUSS:
            phi = np.array([(1 - s) * (1 - t), s * (1 - t), (1 - s) * t, s * t])
            ds = np.array([-(1 - t), 1 - t, -t, t])
            dt = np.array([-(1 - s), -s, 1 - s, s])
            jx, jy = np.einsum("cka,k->ca", xc, ds), np.einsum("cka,k->ca", xc, dt)
            det = jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0]
            assert np.all(det > 0.0)
            local = 0.25 * det[:, None, None] * phi[None, :, None] * phi[None, None, :]
            np.add.at(mc, (cells[:, :, None], cells[:, None, :]), local)
    return mc


@pytest.mark.parametrize("kind", ["jittered", "mixed valence"])
def test_exact_for_a_q1_field(kind):
    if kind == "jittered":
        cells, coords = _mesh(20, 15, dx=0.1, dy=0.1, jitter=0.3, seed=1)
    else:
        cells, coords = _tri_quad_mesh(12, 9, 0.15, seed=1)
        valence = np.bincount(cells.ravel())
        assert valence.min() == 1 and set(valence[valence > 2]) == {3, 4, 6}
    h = 1.0 + 0.3 * coords[:, 0] - 0.2 * coords[:, 1]
    b = _mass_matrix(cells, coords) @ h
    proj = MeshProjector(cells, coords)
    assert np.max(np.abs(proj.consistent(b[:, None])[:, 0] - h)) < 1e-13
    out = proj.project(b[:, None])[:, 0]
    assert np.max(np.abs(out - h)) < 1e-12
    assert proj.limited == 0 and 0 < proj.solver_iterations < 100
    nodes = np.flatnonzero(b)
    index, hn = proj.project_nodes(nodes, b[nodes])
    assert np.array_equal(index, np.arange(coords.shape[0]))
    assert np.max(np.abs(hn - h)) < 1e-12
    # lumped mass = ∫ φ_i = row sums of M_C
    assert np.allclose(proj.lumped_mass, _mass_matrix(cells, coords).sum(axis=1), rtol=1e-14)


def _step_sums(coords, seed, width):
    rng = np.random.default_rng(seed)
    b = rng.uniform(0.0, 1.0, (coords.shape[0], 2))
    b[:, 0] *= coords[:, 0] < width
    return b


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_grid_projector_on_a_structured_grid(seed):
    nx, ny, dx, dy = 40, 30, 0.7, 1.3
    cells, coords = _mesh(nx, ny, dx, dy)
    b = _step_sums(coords, seed, 0.45 * nx * dx)
    grid, mesh = GridProjector((nx, ny), (dx, dy)), MeshProjector(cells, coords)
    # the mesh's Jacobians come from coordinate differences: each carries up to one ulp of the
    # coordinate (|x| up to 28 m for a 0.7 m edge), so the masses agree to a few ulps of
    # |x|/dx + |y|/dy relative (the reduction order of numpy's sums varies with the CPU)
    bound = 8 * np.finfo(float).eps * (nx + ny)
    assert np.allclose(mesh.lumped_mass, grid.lumped_mass, rtol=bound, atol=0.0)
    ref, out = grid.project(b), mesh.project(b)
    assert grid.limited > 0  # the FCT limited fluxes
    assert mesh.limited == grid.limited
    assert np.max(np.abs(out - ref)) < 1e-12 * np.max(np.abs(ref))
    nodes = np.flatnonzero(b[:, 0])
    gi, gh = grid.project_nodes(nodes, b[nodes, 0])
    mi, mh = mesh.project_nodes(nodes, b[nodes, 0])
    full_g, full_m = np.zeros(len(coords)), np.zeros(len(coords))
    full_g[gi], full_m[mi] = gh, mh
    assert np.max(np.abs(full_m - full_g)) < 1e-12 * np.max(gh)


@pytest.mark.parametrize("seed", [3, 4])
@pytest.mark.parametrize("kind", ["jittered", "mixed valence"])
def test_conservation_and_positivity(seed, kind):
    if kind == "jittered":
        cells, coords = _mesh(36, 28, dx=0.5, dy=0.5, jitter=0.3, seed=seed)
    else:
        cells, coords = _tri_quad_mesh(28, 22, 0.65, seed=seed)
    rng = np.random.default_rng(seed)
    b = np.where(coords[:, 0] < 7.0, 1.0, 1e-3) * rng.uniform(0.5, 1.5, coords.shape[0])
    proj = MeshProjector(cells, coords)
    h = proj.project(b[:, None])[:, 0]
    assert proj.limited > 0
    assert np.all(h >= 0.0)
    assert abs(proj.lumped_mass @ h - b.sum()) < 1e-13 * b.sum()
    index, hn = proj.project_nodes(np.arange(len(b)), b)
    assert np.array_equal(hn, h[index])


def test_window_truncation_is_round_off():
    cells, coords = _mesh(120, 120, dx=1.0, dy=1.0, jitter=0.3, seed=5)
    proj = MeshProjector(cells, coords)
    n = coords.shape[0]
    rng = np.random.default_rng(5)
    jj, ii = np.meshgrid(np.arange(55, 63), np.arange(50, 60), indexing="ij")
    nodes = np.sort((jj * 121 + ii).ravel())
    values = rng.uniform(0.2, 1.0, nodes.size)
    index, h = proj.project_nodes(nodes, values)
    assert 2000 < index.size < 5000 and proj.limited > 0
    b = np.zeros((n, 1))
    b[nodes, 0] = values
    whole = proj._blend(np.arange(n), b)[:, 0]  # the projection on the whole mesh
    windowed = np.zeros(n)
    windowed[index] = h
    assert np.max(np.abs(windowed - whole)) < 1e-12 * np.max(whole)
    assert np.array_equal(proj.project(b)[:, 0], windowed)
    full = proj.consistent(b)[:, 0]
    part = proj.consistent(b[index], index)[:, 0]
    assert np.max(np.abs(part - full[index])) < 1e-12 * np.max(np.abs(full))
    assert abs(proj.lumped_mass[index] @ h - values.sum()) < 1e-13 * values.sum()


def _largest_change(proj, a, b, moves):
    """Largest change of the projected depth along ``(1 - t) a + t b`` in ``moves`` moves."""
    largest, previous = 0.0, None
    for t in np.linspace(0.0, 1.0, moves + 1):
        h = proj.project((1.0 - t) * a + t * b)[:, 0]
        if previous is not None:
            largest = max(largest, np.abs(h - previous).max())
        previous = h
    return largest


def test_continuous_in_the_sums():
    """Sums moving from one front to another on a jittered mesh: halving every move halves the
    largest change of the projection (continuous in the data). The former cell-wise switch
    jumped: its largest change stayed the same whatever the move's size."""
    cells, coords = _mesh(24, 18, dx=0.5, dy=0.5, jitter=0.3, seed=7)
    proj = MeshProjector(cells, coords)
    a, b = _step_sums(coords, 1, 5.0)[:, :1], _step_sums(coords, 2, 6.0)[:, :1]
    coarse, fine = _largest_change(proj, a, b, 1000), _largest_change(proj, a, b, 2000)
    assert fine <= 0.55 * coarse


def test_empty_and_deterministic():
    cells, coords = _mesh(30, 30, jitter=0.3, seed=6)
    proj = MeshProjector(cells, coords)
    index, h = proj.project_nodes(np.zeros(0, dtype=np.int64), np.zeros(0))
    assert index.size == 0 and h.size == 0
    assert not proj.project(np.zeros((len(coords), 2))).any()
    b = _step_sums(coords, 7, 12.0)
    first = proj.project(b)
    proj.project(_step_sums(coords, 8, 20.0))  # results depend on the inputs only
    assert np.array_equal(proj.project(b), first)


def _dot_in_order(x, y):
    """``x · y`` summed in index order, one float at a time."""
    s = 0.0
    for a, b in zip(x.tolist(), y.tolist(), strict=True):
        s += a * b
    return s


def _matvec_by_cells(ids, lc, emass, x):
    """``M_C x`` on a window, cell by cell in cell order (the projector's order)."""
    y = [0.0] * x.size
    for t, cell in enumerate(ids.tolist()):
        m = emass[cell].tolist()
        v = [x[i] for i in lc[t]]
        for q in range(4):
            y[lc[t, q]] += m[q][0] * v[0] + m[q][1] * v[1] + m[q][2] * v[2] + m[q][3] * v[3]
    return np.array(y)


def _cg_one_pass_each(ids, lc, emass, b, rtol, max_it):
    """Jacobi-preconditioned CG written out one operation at a time (before session 52)."""
    n, k = b.shape
    diag = np.zeros(n)
    for t, cell in enumerate(ids):
        for q in range(4):
            diag[lc[t, q]] += emass[cell, q, q]
    inv = 1.0 / diag
    x = np.zeros((n, k))
    for m in range(k):
        r = b[:, m].copy()
        z = r * inv
        p = z.copy()
        stop = rtol * np.sqrt(_dot_in_order(r, r))
        rz, it = _dot_in_order(r, z), 0
        while it < max_it and np.sqrt(_dot_in_order(r, r)) > stop:
            w = _matvec_by_cells(ids, lc, emass, p)
            alpha = rz / _dot_in_order(p, w)
            x[:, m] += alpha * p
            r -= alpha * w
            z = r * inv
            rz, rz_old = _dot_in_order(r, z), rz
            p = z + (rz / rz_old) * p
            it += 1
    return x


def test_the_fused_cg_and_the_scans_give_the_bits_of_their_definitions():
    """The consistent solve's CG (fused passes) gives the bits of CG written one operation
    at a time; the window (rings by a scan of marks, no sort) and its cells are the sorted
    sets of their definitions."""
    from mpm.mesh_projection import CG_MAX_ITERATIONS, CG_RTOL, WINDOW_RINGS

    cells, coords = _tri_quad_mesh(24, 18, 1.0, seed=3)
    proj = MeshProjector(cells, coords)
    rng = np.random.default_rng(7)
    seeds = np.unique(rng.integers(0, 500, 4))
    near = seeds
    for _ in range(WINDOW_RINGS):  # the nodes of every cell touching the set
        near = np.unique(cells[np.isin(cells, near).any(axis=1)])
    index = proj.window(seeds)
    assert np.array_equal(index, near) and 0 < index.size < proj.n_nodes
    ids = np.flatnonzero(np.isin(cells, index).all(axis=1))
    lc = np.searchsorted(index, cells[ids])
    b = rng.uniform(0.0, 2.0, (index.size, 2))
    want = _cg_one_pass_each(ids, lc, proj.element_mass, b, CG_RTOL, CG_MAX_ITERATIONS)
    assert np.array_equal(proj.consistent(b, index), want)
    assert 10 < proj.solver_iterations < CG_MAX_ITERATIONS
