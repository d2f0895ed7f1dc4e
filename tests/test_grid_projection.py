"""DAMPM's projection of particle sums onto the structured grid (mpm.projection).

The tridiagonal consistent-mass solves, the continuity of the FCT blend in the particles'
positions, and the window and flow-support projections against the whole grid's.
"""

import numpy as np

from mpm.projection import GridProjector, tridiagonal_mass_solve


def test_tridiagonal_mass_solve_matches_a_dense_solve():
    n = 9
    m = (np.diag(np.full(n, 4.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1))
    m[0, 0] = m[-1, -1] = 2.0
    rhs = np.random.default_rng(2).random((3, n))
    x = tridiagonal_mass_solve(rhs)
    assert np.abs(x @ (m / 6.0).T - rhs).max() < 1e-14


def _point_sums(shape, spacing, points):
    """Sums ``b_i = Σ_p V_p N_i(x_p)`` of particles ``(x, y, V)`` on a structured grid."""
    ny1, nx1 = shape
    b = np.zeros((ny1 * nx1, 1))
    for x, y, volume in points:
        i, j = int(x // spacing), int(y // spacing)
        xi, eta = x / spacing - i, y / spacing - j
        for di, dj, w in ((0, 0, (1 - xi) * (1 - eta)), (1, 0, xi * (1 - eta)),
                          (0, 1, (1 - xi) * eta), (1, 1, xi * eta)):
            b[(j + dj) * nx1 + i + di, 0] += volume * w
    return b


def _largest_step(proj, spacing, moves):
    """Largest change of the projected depth over ``moves`` equal moves of three particles."""
    largest, previous = 0.0, None
    for t in np.linspace(0.0, 1.0, moves + 1):
        b = _point_sums(proj.shape, spacing, [(4.3 + 1.7 * t, 4.4 + 0.9 * t, 0.3),
                                              (5.6, 5.2 - 0.3 * t, 0.5),
                                              (6.05 - 0.4 * t, 4.8, 0.2)])
        h = proj.project(b)[:, 0]
        assert h.min() >= 0.0 and abs(proj.lumped_mass @ h - 1.0) < 1e-14
        if previous is not None:
            largest = max(largest, np.abs(h - previous).max())
        previous = h
    return largest


def test_projection_is_continuous_in_the_particles_positions():
    """Three particles drifting across cells: halving every move halves the largest change
    of the projected depth (continuous, Lipschitz in the positions). The former cell-wise
    switch (``α_K = 0`` around a node below zero) jumped by 0.063 m whatever the move's size
    (0.0620, 0.0625, 0.0627 m for 1 000, 2 000, 4 000 moves): an output that jumps when the
    data change by round-off."""
    spacing = 1.0
    proj = GridProjector((12, 10), (spacing, spacing))
    coarse, fine = _largest_step(proj, spacing, 1000), _largest_step(proj, spacing, 2000)
    assert fine <= 0.55 * coarse
    assert proj.limited > 0  # the undershoots around the particles are ramped or limited


def test_tridiagonal_solve_with_truncated_ends_matches_a_dense_solve():
    n = 9
    m = (np.diag(np.full(n, 4.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1))
    m[-1, -1] = 2.0  # first row inside the grid (truncated), last one a domain end
    rhs = np.random.default_rng(3).random((2, n))
    x = tridiagonal_mass_solve(rhs, False, True)
    assert np.abs(x @ (m / 6.0).T - rhs).max() < 1e-14


def test_projection_on_a_window_is_the_whole_grid_projection_to_round_off():
    """Issue 16: a particle cluster in a corner of a 200 x 150 grid; the window's truncation
    (24 nodes of margin, M_C^{-1} decaying like 0.27^k) changes nothing above round-off."""
    from mpm.projection import WINDOW_MARGIN

    proj = GridProjector((200, 150), (2.0, 3.0))
    ny1, nx1 = proj.shape
    rng = np.random.default_rng(5)
    sums = np.zeros((ny1 * nx1, 2))
    j, i = np.meshgrid(np.arange(10, 30), np.arange(20, 45), indexing="ij")
    nodes = (j * nx1 + i).ravel()
    sums[nodes, 0] = 6.0 * (1.0 + rng.random(nodes.size))
    sums[nodes, 1] = rng.random(nodes.size) - 0.5
    window = proj.window(sums[:, 0])
    assert window is not None and window[1] - window[0] < ny1 and window[3] - window[2] < nx1
    assert window[0] == 0 and window[2] == 0  # clipped at the grid's sides
    out = proj.project(sums)
    # the reference: the same blend on the whole grid (a window that is the whole grid)
    full = GridProjector((200, 150), (2.0, 3.0))
    full.window = lambda weights: (0, ny1, 0, nx1)
    ref = full.project(sums)
    scale = np.abs(ref[:, 0]).max()
    assert np.abs(out - ref).max() <= 1e-12 * scale
    assert WINDOW_MARGIN >= 20
    assert abs(np.sum(proj.lumped_mass * out[:, 0]) - np.sum(sums[:, 0])) < 1e-9


def test_projection_on_the_flow_support_is_the_window_projection_to_round_off():
    """Issue 16: the solver's projection solves each line on the flow's support only
    (mpm/projection_support.py). On a diagonal band, two far blobs and a cluster at the
    grid's corner it equals the window projection to round-off (the two truncations are
    0.27^24 apart), conserves the volume, stays >= 0 and covers less than the window."""
    proj = GridProjector((220, 259), (10.0, 10.0))
    ny1, nx1 = proj.shape
    rng = np.random.default_rng(11)
    sums = np.zeros(ny1 * nx1)
    for t in range(150):  # a band 15 nodes wide running diagonally, like a gully's flow
        j, i0 = 40 + t, 30 + int(0.8 * t)
        sums[j * nx1 + i0: j * nx1 + i0 + 15] = 50.0 * rng.random(15)
    sums[200 * nx1 + 150] = 3.0  # an isolated node
    sums[nx1 + 200: nx1 + 205] = 1.0  # a few nodes next to the bottom side
    sums[(ny1 - 1) * nx1: (ny1 - 1) * nx1 + 3] = 2.0  # the top-left corner
    nodes = np.flatnonzero(sums)
    ref = proj.project(sums[:, None])[:, 0]
    index, h = proj.project_nodes(nodes, sums[nodes])
    assert np.all(np.diff(index) > 0) and h.min() >= 0.0
    out = np.zeros_like(ref)
    out[index] = h
    assert np.abs(out - ref).max() <= 1e-12 * ref.max()
    assert abs(np.sum(proj.lumped_mass * out) - sums.sum()) <= 1e-13 * sums.sum()
    window = proj.window(sums)
    assert index.size < 0.7 * (window[1] - window[0]) * (window[3] - window[2])
    single = np.zeros_like(sums)  # a lone particle: the FCT blend keeps h >= 0 there too
    single[100 * nx1 + 100] = 1.0
    index, h = proj.project_nodes(np.array([100 * nx1 + 100]), np.array([1.0]))
    whole = proj.project(single[:, None])[:, 0]
    assert h.min() >= 0.0 and np.abs(h - whole[index]).max() <= 1e-12 * whole.max()
    # volume: exact but for the clamp of the bound's round-off negatives
    clamp = 1e-13 * (1.0 / proj.lumped_mass[100 * nx1 + 100]) * proj.lumped_mass[index].sum()
    assert abs(np.sum(proj.lumped_mass[index] * h) - 1.0) <= clamp
