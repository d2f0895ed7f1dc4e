"""The mesh partition by the flow's path (issue 16): routing, travel angle, stripes."""

import numpy as np

from fem_runout.partition import (
    PATH_HALF_WIDTH,
    PIECES_PER_RANK,
    path_owners,
    reachable,
    strip_owners,
)


def test_routing_follows_the_steepest_descent_and_stops_at_the_travel_angle():
    nx, ny, dx = 200, 41, 10.0
    x = (np.arange(nx) + 0.5) * dx
    ground = np.where(x < 500.0, 1000.0 - 0.6 * x, 700.0 - 0.1 * (x - 500.0))  # 31°, then 5.7°
    z = np.tile(ground, (ny, 1)) + 0.01 * np.abs(np.arange(ny) - 20)[:, None]  # a gentle gully
    source = np.zeros((ny, nx), dtype=bool)
    source[20, 2] = True
    angle = 12.0
    path = reachable(z, source, (dx, dx), angle)
    # the energy line from the release, falling at tan 12°, meets the 5.7° ground here:
    tan = np.tan(np.radians(angle))
    d = np.abs(x - x[2])
    line = z[20, 2] - tan * d
    stop = x[np.flatnonzero((line >= z[20]) & (x >= x[2]))[-1]]
    reached = x[np.flatnonzero(path[20])]
    assert abs(reached.max() - stop) <= dx  # within one cell of the exact stop
    assert path[:, : 2].any() and not path[20 + PATH_HALF_WIDTH + 1:].any()  # a narrow path
    assert path[20 - PATH_HALF_WIDTH:21 + PATH_HALF_WIDTH, 10].all()  # widened to 2 k + 1


def test_pieces_along_the_path_hold_equal_shares_of_it():
    nx, ny, cell = 300, 60, 10.0
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    x, y = (ii.ravel() + 0.5) * cell, (jj.ravel() + 0.5) * cell
    # a straight and an oblique path, and a path that widens (a fan): equal lengths would give
    # the wide end most of the cells; the cuts hold equal shares to within one cross-section
    for tilt, widen, tol in ((0.0, 0.0, 0.02), (0.2, 0.0, 0.02), (0.0, 0.04, 0.03)):
        on_path = (np.abs(y - 300.0 - tilt * x) < 40.0 + widen * x) & (x < 2000.0)
        for parts in (2, 3, 4):
            owners = strip_owners(x, y, on_path.astype(float), parts)
            share = np.bincount(owners[on_path], minlength=parts) / on_path.sum()
            assert np.abs(share - 1.0 / parts).max() < tol, (tilt, share)
            columns = np.unique(x[on_path])  # mean owner per column: in order along the path
            mean = np.array([owners[on_path & (x == c)].mean() for c in columns])
            step = np.diff(mean)
            assert np.all(step >= 0) or np.all(step <= 0)


def test_path_pieces_are_dealt_to_the_ranks_in_turn():
    nx, ny, dx = 200, 41, 10.0
    x = (np.arange(nx) + 0.5) * dx
    ground = np.where(x < 500.0, 1000.0 - 0.6 * x, 700.0 - 0.1 * (x - 500.0))
    z = np.tile(ground, (ny, 1)) + 0.01 * np.abs(np.arange(ny) - 20)[:, None]
    released = np.zeros((ny, nx))
    released[18:23, 2:6] = 2.0
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    centres = np.stack([(ii.ravel() + 0.5) * dx, (jj.ravel() + 0.5) * dx], axis=1)
    path = reachable(z, released > 0.0, (dx, dx)).ravel()
    for parts in (2, 3):
        owners = path_owners(centres, z.ravel(), released.ravel(), (nx, ny), (dx, dx), parts)
        share = np.bincount(owners[path], minlength=parts) / path.sum()
        assert np.abs(share - 1.0 / parts).max() < 0.05, share
        # along the path the owner changes PIECES_PER_RANK * parts - 1 times: 0, 1, (2,) 0, 1...
        columns = np.unique(centres[path, 0])
        first = np.array([owners[path & (centres[:, 0] == c)].min() for c in columns])
        runs = first[np.r_[True, np.diff(first) != 0]]
        assert runs.tolist() == [k % parts for k in range(PIECES_PER_RANK * parts)]
