"""Q1 fields of an unstructured mesh sampled at raster pixel centres (hazard maps, issue 17).

Every rank locates the pixel centres inside its owned cells (inverse bilinear map by Newton's
method) and evaluates the Q1 interpolant there; rank 0 keeps, for a pixel on an edge shared by
two cells, the cell with the smaller input index, so the rasters do not depend on the
partition. Pixels outside the mesh are NaN (written as nodata).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["bed_cosine_nodes", "locate_pixels", "sample_points", "sample_q1"]

_INSIDE = 1e-10  # tolerance on the reference coordinates (pixels on an edge)


def bed_cosine_nodes(disc, z: np.ndarray) -> np.ndarray:
    """``cosθ = 1/sqrt(1 + |∇Z|²)`` at the local nodes (lumped projection of ``∇Z``)."""
    from fem_runout.physics.slope import nodal_gradient

    grad = nodal_gradient(disc.cell_sum, disc.C, disc.cell_nodes, disc.lumped_mass,
                          np.ascontiguousarray(z, dtype=float), disc.n_owned_cells)
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
def _locate(xcells, x0, dx, nx, y0, dy, ny, pix, ref, which):
    """Append (pixel, cell, X, Y) of every pixel centre inside each cell; return the count."""
    n = 0
    for c in range(xcells.shape[0]):
        xc = xcells[c]
        lo_x, hi_x = xc[:, 0].min(), xc[:, 0].max()
        lo_y, hi_y = xc[:, 1].min(), xc[:, 1].max()
        i0 = max(0, int(np.ceil((lo_x - x0) / dx - 1e-9)))
        i1 = min(nx - 1, int(np.floor((hi_x - x0) / dx + 1e-9)))
        j0 = max(0, int(np.ceil((lo_y - y0) / dy - 1e-9)))
        j1 = min(ny - 1, int(np.floor((hi_y - y0) / dy + 1e-9)))
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                X, Y = _inverse(xc, x0 + i * dx, y0 + j * dy)
                if -_INSIDE <= X <= 1 + _INSIDE and -_INSIDE <= Y <= 1 + _INSIDE:
                    if n == pix.shape[0]:
                        return -1
                    pix[n] = j * nx + i
                    ref[n, 0], ref[n, 1] = X, Y
                    which[n] = c
                    n += 1
    return n


def locate_pixels(xcells: np.ndarray, xs: np.ndarray, ys: np.ndarray):
    """Find the pixel centres (grid ``xs`` × ``ys``, ascending) inside each bilinear cell.

    Args:
        xcells: (n_cells, 4, 2) node coordinates in the DOLFINx quadrilateral order.
        xs: Ascending, evenly spaced pixel-centre x.
        ys: Ascending, evenly spaced pixel-centre y.

    Returns:
        ``(pixel, cell, ref)``: flat pixel index ``j len(xs) + i``, cell row and reference
        coordinates (X, Y) of every hit.
    """
    nx, ny = xs.size, ys.size
    dx = float(xs[1] - xs[0]) if nx > 1 else 1.0
    dy = float(ys[1] - ys[0]) if ny > 1 else 1.0
    size = max(1024, 4 * xcells.shape[0])
    while True:
        pix, ref = np.empty(size, np.int64), np.empty((size, 2))
        which = np.empty(size, np.int64)
        n = _locate(np.ascontiguousarray(xcells, dtype=float), float(xs[0]) if nx else 0.0, dx,
                    nx, float(ys[0]) if ny else 0.0, dy, ny, pix, ref, which)
        if n >= 0:
            return pix[:n], which[:n], ref[:n]
        size *= 2


def sample_q1(disc, values: dict[str, np.ndarray], xs: np.ndarray,
              ys: np.ndarray) -> dict[str, np.ndarray] | None:
    """Sample nodal Q1 fields at the pixel centres ``xs`` × ``ys`` (collective).

    Args:
        disc: The discretization (:class:`fem_runout.mesh.Discretization`).
        values: Name -> local nodal values (owned then ghosts).
        xs: Ascending, evenly spaced pixel-centre x.
        ys: Ascending, evenly spaced pixel-centre y.

    Returns:
        On rank 0, name -> (len(ys), len(xs)) array, NaN outside the mesh; None elsewhere.
    """
    n = disc.n_owned_cells
    cells = disc.cell_nodes[:n]
    key = np.asarray(disc.mesh.topology.original_cell_index[:n], dtype=np.int64)
    pix, which, ref = locate_pixels(disc.coords[cells], xs, ys)
    X, Y = ref[:, 0], ref[:, 1]
    phi = np.stack([(1 - X) * (1 - Y), X * (1 - Y), (1 - X) * Y, X * Y], axis=1)
    names = sorted(values)
    local = np.column_stack([pix.astype(float), key[which].astype(float)]
                            + [np.einsum("ka,ka->k", phi, values[k][cells[which]])
                               for k in names]) if pix.size else np.empty((0, 2 + len(names)))
    parts = disc.comm.gather(local, root=0)
    if disc.comm.rank != 0:
        return None
    rows = np.concatenate(parts)
    order = np.lexsort((rows[:, 1], rows[:, 0]))  # by pixel, then the smaller cell key first
    rows = rows[order]
    first = np.r_[True, rows[1:, 0] != rows[:-1, 0]] if rows.size else np.zeros(0, bool)
    rows = rows[first]
    out = {}
    for c, k in enumerate(names):
        grid = np.full(xs.size * ys.size, np.nan)
        grid[rows[:, 0].astype(np.int64)] = rows[:, 2 + c]
        out[k] = grid.reshape(ys.size, xs.size)
    return out


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
