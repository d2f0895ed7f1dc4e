"""The mesh partition by the flow's path (issue 16): routing, travel angle, stripes."""

import numpy as np

from fem_runout.partition import (
    PATH_HALF_WIDTH,
    PIECES_PER_RANK,
    main_axis,
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


def test_path_pieces_are_dealt_to_the_ranks_in_turn_from_the_release():
    nx, ny, dx = 200, 41, 10.0
    x = (np.arange(nx) + 0.5) * dx
    ground = np.where(x < 500.0, 1000.0 - 0.6 * x, 700.0 - 0.1 * (x - 500.0))
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    centres = np.stack([(ii.ravel() + 0.5) * dx, (jj.ravel() + 0.5) * dx], axis=1)
    # the slope falling to +x, and mirrored (falling to -x): rank 0 holds the release's piece
    for mirror in (False, True):
        z = np.tile(ground[::-1] if mirror else ground, (ny, 1))
        z = z + 0.01 * np.abs(np.arange(ny) - 20)[:, None]
        released = np.zeros((ny, nx))
        released[18:23, slice(nx - 6, nx - 2) if mirror else slice(2, 6)] = 2.0
        path = reachable(z, released > 0.0, (dx, dx)).ravel()
        for parts in (2, 3):
            owners = path_owners(centres, z.ravel(), released.ravel(), (nx, ny), (dx, dx), parts)
            share = np.bincount(owners[path], minlength=parts) / path.sum()
            assert np.abs(share - 1.0 / parts).max() < 0.05, share
            # from the release the owner changes PIECES_PER_RANK * parts - 1 times: 0, 1, (2,) 0..
            columns = np.unique(centres[path, 0])[:: -1 if mirror else 1]
            first = np.array([owners[path & (centres[:, 0] == c)].min() for c in columns])
            runs = first[np.r_[True, np.diff(first) != 0]]
            assert runs.tolist() == [k % parts for k in range(PIECES_PER_RANK * parts)], mirror


def test_the_main_axis_is_the_covariances_and_its_sign_is_fixed():
    rng = np.random.default_rng(7)
    for angle in (0.0, 0.3, 1.2, np.pi / 2, 2.5, -0.7):
        t = rng.normal(size=4000) * 300.0  # along the axis
        n = rng.normal(size=4000) * 40.0  # across it
        c, s = np.cos(angle), np.sin(angle)
        x, y = 1000.0 + c * t - s * n, 2000.0 + s * t + c * n
        w = rng.uniform(0.5, 1.5, size=t.size)
        mx, my, ax, ay = main_axis(x, y, w)
        assert abs(mx - np.average(x, weights=w)) < 1e-9
        assert abs(my - np.average(y, weights=w)) < 1e-9
        _, vecs = np.linalg.eigh(np.cov(np.stack([x, y]), aweights=w))
        assert abs(abs(ax * vecs[0, 1] + ay * vecs[1, 1]) - 1.0) < 1e-12  # the same axis
        assert abs(np.hypot(ax, ay) - 1.0) < 1e-15
        big = ax if abs(ax) >= abs(ay) else ay
        assert big > 0.0  # without an origin: towards +x (+y)
        for origin in ((x[np.argmin(t)], y[np.argmin(t)]), (x[np.argmax(t)], y[np.argmax(t)])):
            _, _, bx, by = main_axis(x, y, w, origin)
            assert (origin[0] - mx) * bx + (origin[1] - my) * by < 0.0  # pointing away from it
            assert abs(abs(bx * ax + by * ay) - 1.0) < 1e-15
