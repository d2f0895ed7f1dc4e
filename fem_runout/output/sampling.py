"""Q1 fields of an unstructured mesh sampled at raster pixel centres (hazard maps, issue 17).

Every rank locates the points (pixel centres, points along rays) inside its owned cells
(inverse bilinear map by Newton's method) and evaluates the Q1 interpolant there; rank 0
keeps, for a point on an edge shared by two cells, the cell with the smaller input index, so
the rasters do not depend on the partition. Points outside the mesh are NaN (written as
nodata).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["bed_cosine_nodes", "ghosted", "ray_front_radii", "sample_points", "sample_q1"]

_INSIDE = 1e-10  # tolerance on the reference coordinates (pixels on an edge)


def bed_cosine_nodes(disc, z: np.ndarray) -> np.ndarray:
    """``cosθ = 1/sqrt(1 + |∇Z|²)`` at the local nodes (lumped projection of ``∇Z``)."""
    from fem_runout.physics.slope import lumped_gradient

    grad = lumped_gradient(disc, z)
    return 1.0 / np.sqrt(1.0 + grad[:, 0] ** 2 + grad[:, 1] ** 2)


@numba.njit(cache=True)
def _inverse(xc, px, py):
    """Return the reference coordinates (X, Y) of (px, py) in the bilinear cell ``xc``."""
    X, Y = 0.5, 0.5
    for _ in range(20):
        a0, a1, a2, a3 = (1 - X) * (1 - Y), X * (1 - Y), (1 - X) * Y, X * Y
        fx = a0 * xc[0, 0] + a1 * xc[1, 0] + a2 * xc[2, 0] + a3 * xc[3, 0] - px
        fy = a0 * xc[0, 1] + a1 * xc[1, 1] + a2 * xc[2, 1] + a3 * xc[3, 1] - py
        jxx = (1 - Y) * (xc[1, 0] - xc[0, 0]) + Y * (xc[3, 0] - xc[2, 0])
        jyx = (1 - Y) * (xc[1, 1] - xc[0, 1]) + Y * (xc[3, 1] - xc[2, 1])
        jxy = (1 - X) * (xc[2, 0] - xc[0, 0]) + X * (xc[3, 0] - xc[1, 0])
        jyy = (1 - X) * (xc[2, 1] - xc[0, 1]) + X * (xc[3, 1] - xc[1, 1])
        det = jxx * jyy - jxy * jyx
        dX = (jyy * fx - jxy * fy) / det
        dY = (-jyx * fx + jxx * fy) / det
        X -= dX
        Y -= dY
        if abs(dX) + abs(dY) < 1e-14:
            break
    return X, Y


@numba.njit(cache=True)
def _locate_points(xcells, sx, sy, order, found, ref, which, key, keys):
    """For points sorted by x (``sx``), the cell (smallest key) and reference coordinates."""
    for c in range(xcells.shape[0]):
        xc = xcells[c]
        lo_x, hi_x = xc[:, 0].min(), xc[:, 0].max()
        lo_y, hi_y = xc[:, 1].min(), xc[:, 1].max()
        k = np.searchsorted(sx, lo_x - 1e-9 * (1.0 + abs(lo_x)))
        while k < sx.shape[0] and sx[k] <= hi_x + 1e-9 * (1.0 + abs(hi_x)):
            p = order[k]
            if lo_y - 1e-9 * (1.0 + abs(lo_y)) <= sy[k] <= hi_y + 1e-9 * (1.0 + abs(hi_y)):
                X, Y = _inverse(xc, sx[k], sy[k])
                inside = -_INSIDE <= X <= 1 + _INSIDE and -_INSIDE <= Y <= 1 + _INSIDE
                if inside and (not found[p] or keys[c] < key[p]):
                    found[p] = True
                    key[p] = keys[c]
                    ref[p, 0], ref[p, 1] = X, Y
                    which[p] = c
            k += 1


def sample_points(disc, values: dict[str, np.ndarray],
                  points: np.ndarray) -> dict[str, np.ndarray] | None:
    """Evaluate nodal Q1 fields at arbitrary points (collective; NaN outside the mesh).

    Args:
        disc: The discretization.
        values: Name -> local nodal values (owned then ghosts).
        points: (m, 2) coordinates, the same on every rank.

    Returns:
        On rank 0, name -> (m,) values; None elsewhere.
    """
    n = disc.n_owned_cells
    cells = disc.cell_nodes[:n]
    keys = np.asarray(disc.mesh.topology.original_cell_index[:n], dtype=np.int64)
    order = np.argsort(points[:, 0], kind="stable")
    m = points.shape[0]
    found, key = np.zeros(m, bool), np.zeros(m, np.int64)
    ref, which = np.zeros((m, 2)), np.zeros(m, np.int64)
    _locate_points(np.ascontiguousarray(disc.coords[cells]), points[order, 0].copy(),
                   points[order, 1].copy(), order, found, ref, which, key, keys)
    X, Y = ref[:, 0], ref[:, 1]
    phi = np.stack([(1 - X) * (1 - Y), X * (1 - Y), (1 - X) * Y, X * Y], axis=1)
    names = sorted(values)
    local = np.column_stack([found.astype(float), key.astype(float)]
                            + [np.einsum("ka,ka->k", phi, values[k][cells[which]])
                               for k in names])
    parts = disc.comm.gather(local, root=0)
    if disc.comm.rank != 0:
        return None
    stack = np.stack(parts)  # (ranks, m, 2 + k)
    rank_key = np.where(stack[..., 0] > 0, stack[..., 1], np.inf)
    best = np.argmin(rank_key, axis=0)
    pick = stack[best, np.arange(m)]
    hit = np.isfinite(rank_key.min(axis=0))
    return {k: np.where(hit, pick[:, 2 + c], np.nan) for c, k in enumerate(names)}


def ghosted(disc, values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Local nodal arrays (owned then ghosts) from the owned entries of ``values`` (collective).

    The samplers evaluate a cell from all of its nodes, ghosts included; fields kept on the
    owned nodes only (the hazard tracks, the peak envelope) get their ghosts from the owners.

    Args:
        disc: The discretization.
        values: Name -> array whose first ``disc.n_owned_nodes`` entries are the owned values.
    """
    n = disc.n_owned_nodes
    out = {}
    for name, v in values.items():
        local = np.zeros(disc.coords.shape[0])
        local[:n] = v[:n]
        disc.update_ghosts(local)
        out[name] = local
    return out


def sample_q1(disc, values: dict[str, np.ndarray], xs: np.ndarray,
              ys: np.ndarray) -> dict[str, np.ndarray] | None:
    """Sample nodal Q1 fields on the pixel-centre grid ``xs`` × ``ys`` (collective).

    Args:
        disc: The discretization.
        values: Name -> local nodal values (owned then ghosts).
        xs: Pixel-centre x.
        ys: Pixel-centre y.

    Returns:
        On rank 0, name -> (len(ys), len(xs)) array, NaN outside the mesh; None elsewhere.
    """
    X, Y = np.meshgrid(xs, ys)
    got = sample_points(disc, values, np.column_stack([X.ravel(), Y.ravel()]))
    return None if got is None else {k: v.reshape(X.shape) for k, v in got.items()}


def ray_front_radii(disc, h: np.ndarray, centre: tuple[float, float], angles: np.ndarray,
                    r_max: float, threshold: float, step: float = 0.005) -> np.ndarray | None:
    """Front radius along rays from ``centre``: where the Q1 depth falls to ``threshold``.

    The depth is sampled every ``step`` along each ray; past the last sample above the
    threshold the crossing is interpolated linearly (continuous in the data). Collective.

    Args:
        disc: The discretization.
        h: Local nodal depth (owned then ghosts).
        centre: Start of the rays.
        angles: Ray directions [rad].
        r_max: Length of the rays [m].
        threshold: Wet threshold [m].
        step: Sampling step along the rays [m].

    Returns:
        On rank 0 the radius of each ray [m]; None elsewhere.
    """
    r = np.arange(0.0, r_max, step)
    pts = np.concatenate([np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)])
                          for a in angles])
    got = sample_points(disc, {"h": h}, pts)
    if got is None:
        return None
    out = []
    for depth in np.nan_to_num(got["h"]).reshape(len(angles), r.size):
        wet = np.flatnonzero(depth > threshold)
        k = int(wet[-1]) if wet.size else 0
        share = (depth[k] - threshold) / (depth[k] - depth[k + 1]) if k + 1 < r.size else 0.0
        out.append(r[k] + share * step)
    return np.array(out)
