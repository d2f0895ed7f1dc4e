"""Mesh partition by the region the flow can reach: every rank gets a share of the flow.

A landslide or avalanche covers a small, moving part of its DEM. DOLFINx's graph
partitioner balances *all* cells, so on avaKot one of two ranks held 63 % of the cells the
flow ever wets and the other waited for it in every exchange (TG2-PC ran 1.36× faster on 2
ranks than on 1). Only the cells in the active set cost anything per step
(:mod:`fem_runout.active`), so the partition should balance those.

Where the flow can go is estimated before the run as in the alpha-angle and Flow-Py models:
the release is routed downhill, and a mass stops where the energy line, falling at the
travel angle ``α`` (Heim's *Fahrböschung*) along its path, meets the ground
(:func:`reachable`). With ``α`` = :data:`REACH_ANGLE_DEG` (below the run-out angles of
avalanches, 18-30°, and of most debris flows) the estimate holds the path. The mesh is then
cut across the path's main direction (the principal axis of the path's cells) into pieces
holding equal shares of the path's cells (:func:`strip_owners`), :data:`PIECES_PER_RANK` per
rank, dealt to the ranks in turn from the release's end (0, 1, 0, 1 on 2 ranks), so that every
rank holds flow both in the release and in the run-out zone. The axis is computed with
correctly rounded sums in closed form (:func:`main_axis`), so the pieces and their deal are
the same on any CPU.

On avaKot (TG2-PC, 2 ranks) the owned active cells summed over the run are 4.96 and 8.22
million with DOLFINx's partition and with a cut at the median of the path's cells (the flow
spends most of its time in the release fan and the deposit, not evenly along the path), and
7.07 and 6.12 million with two pieces of equal length. Balanced sums are not enough: the flow
fills the path's upper piece first and the lower one later, so the ranks wait for each other
in turn. What counts is the sum over the steps of the larger rank's share, against the even
split: 1.21 with two pieces, 1.05 with four dealt in turn (2 per rank; 1.08 with 8, 1.05 with
16), and on 3 ranks 1.42 with three pieces, 1.09 with six. More pieces add cut edges, which
cost little now that a step exchanges only the flow's shared nodes
(:mod:`fem_runout.shared_nodes`; with DOLFINx's whole-vector scatters 8 stripes made the run
slower). Cutting the path lengthwise balanced the path's cells but not the flow (the wide
release fan lay on one side). Session 37 (the flow of that time): four pieces of equal length
gave the ranks 11.78 and 10.81 million owned active cells (score 1.050; on 3 ranks 1.115),
four pieces with equal shares of the path's cells 11.50 and 11.09 million (1.039; on 3 ranks
1.106); a mirrored deal (0, 1, 1, 0) scored 1.074.

The partition changes only which rank computes which cell: the results do not depend on it
(tested on 1, 2 and 3 ranks). It applies to cases with ``initial.release``; cases without a
release keep DOLFINx's partitioner.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

__all__ = ["PIECES_PER_RANK", "REACH_ANGLE_DEG", "cell_partitioner", "main_axis", "path_owners",
           "reachable", "strip_owners"]

#: Travel angle [deg] bounding the reachable region (a lower bound of observed run-outs).
REACH_ANGLE_DEG = 12.0
#: Cells added on each side of the routed paths.
PATH_HALF_WIDTH = 3
#: Pieces of the path per rank, dealt in turn (see the module's docstring).
PIECES_PER_RANK = 2


@numba.njit(cache=True)
def _route(z, source, dx, dy, slope):
    """Cells reached by routing the release downhill within the travel angle (see module)."""
    ny, nx = z.shape
    energy = np.where(source, z, -np.inf)  # the energy line's height at the cells reached
    order = np.argsort(-z.ravel())
    for k in order:
        j, i = k // nx, k % nx
        if energy[j, i] == -np.inf:
            continue
        best, bj, bi, step = 0.0, -1, -1, 0.0
        for dj in range(-1, 2):
            for di in range(-1, 2):
                jn, in_ = j + dj, i + di
                if (dj == 0 and di == 0) or jn < 0 or jn >= ny or in_ < 0 or in_ >= nx:
                    continue
                dist = np.hypot(di * dx, dj * dy)
                drop = (z[j, i] - z[jn, in_]) / dist
                if drop > best:
                    best, bj, bi, step = drop, jn, in_, dist
        if bj < 0:
            continue  # a pit: the flow stops
        e = energy[j, i] - slope * step
        if e >= z[bj, bi] and e > energy[bj, bi]:
            energy[bj, bi] = e
    return energy > -np.inf


def reachable(z: np.ndarray, source: np.ndarray, spacing: tuple[float, float],
              angle_deg: float = REACH_ANGLE_DEG) -> np.ndarray:
    """Cells a mass released on ``source`` reaches flowing downhill within the travel angle.

    The steepest downhill neighbour (8 directions) of a reached cell is reached while the
    energy line, falling at ``angle_deg`` along the path from the release, stays above the
    ground (steepest-descent routing of the alpha-angle models), and the paths are widened
    by :data:`PATH_HALF_WIDTH` cells (a flow is wider than its thalweg).

    Args:
        z: (ny, nx) elevation at the cell centres [m].
        source: (ny, nx) release cells (bool).
        spacing: ``(Δx, Δy)`` [m].
        angle_deg: Travel angle [deg].
    """
    path = _route(np.ascontiguousarray(z, dtype=float), source, float(spacing[0]),
                  float(spacing[1]), float(np.tan(np.radians(angle_deg))))
    for _ in range(PATH_HALF_WIDTH):  # widen by one cell (4-neighbours) per pass
        grown = path.copy()
        grown[1:] |= path[:-1]
        grown[:-1] |= path[1:]
        grown[:, 1:] |= path[:, :-1]
        grown[:, :-1] |= path[:, 1:]
        path = grown
    return path


def main_axis(x: np.ndarray, y: np.ndarray, weight: np.ndarray,
              origin: tuple[float, float] | None = None) -> tuple[float, float, float, float]:
    """Weighted centre and unit major axis ``(mx, my, ax, ay)`` of the points, the same on any CPU.

    The centre and second moments are correctly rounded sums (``math.fsum``) and the axis is
    the closed form ``θ = atan2(2 c_xy, c_xx - c_yy) / 2`` of the 2 × 2 covariance, not
    LAPACK's ``eigh``: its eigenvector's sign (and last bits) follow the BLAS kernels of the
    CPU, and a flipped axis dealt the path's pieces to the ranks in the opposite order on
    another CPU. The axis points away from ``origin`` (the release's centre), else to ``+x``
    (``+y`` for an axis along ``y``).

    Args:
        x: Point x [m].
        y: Point y [m].
        weight: Non-negative weight per point (not all zero).
        origin: A point the axis points away from, or None.

    Returns:
        ``(mx, my, ax, ay)``: the weighted centre and the unit vector of the major axis.
    """
    total = math.fsum(weight)
    mx, my = math.fsum(weight * x) / total, math.fsum(weight * y) / total
    dx, dy = x - mx, y - my
    cxx, cxy, cyy = (math.fsum(weight * a * b) for a, b in ((dx, dx), (dx, dy), (dy, dy)))
    theta = 0.5 * math.atan2(2.0 * cxy, cxx - cyy)
    ax, ay = math.cos(theta), math.sin(theta)
    if origin is not None:
        ahead = (origin[0] - mx) * ax + (origin[1] - my) * ay
        sign = -1.0 if ahead > 0.0 else 1.0
    else:
        sign = -1.0 if (ax if abs(ax) >= abs(ay) else ay) < 0.0 else 1.0
    return mx, my, sign * ax, sign * ay


def strip_owners(x: np.ndarray, y: np.ndarray, weight: np.ndarray, nparts: int,
                 origin: tuple[float, float] | None = None) -> np.ndarray:
    """Rank of every cell: pieces with equal shares of the weight along the cells' main axis.

    Args:
        x: Cell centre x [m].
        y: Cell centre y [m].
        weight: Non-negative weight per cell (1 on the estimated path).
        nparts: Number of pieces.
        origin: A point at the path's start (the release): piece 0 is at its end of the
            axis (:func:`main_axis`).

    Returns:
        (n,) int32 piece of every cell: ``nparts`` pieces in order along the path, cut where
        the weight summed along it reaches ``k / nparts`` of the total (cells beyond the
        path's ends go to the first and last piece).
    """
    mx, my, ax, ay = main_axis(x, y, weight, origin)
    s = (x - mx) * ax + (y - my) * ay
    order = np.argsort(s, kind="stable")
    below = np.cumsum(weight[order])
    cuts = s[order][np.searchsorted(below, below[-1] * np.arange(1, nparts) / nparts)]
    return np.searchsorted(cuts, s, side="right").astype(np.int32)


def path_owners(centres: np.ndarray, z: np.ndarray, released: np.ndarray,
                cells: tuple[int, int], spacing: tuple[float, float],
                nparts: int) -> np.ndarray | None:
    """Owner of every structured cell (index ``j nx + i``), or None (nothing released).

    The path is cut into ``PIECES_PER_RANK * nparts`` pieces with equal shares of its cells,
    dealt to the ranks in turn.

    Args:
        centres: (nx ny, 2) cell centres, row-major.
        z: Elevation at the centres [m].
        released: Release depth at the centres [m].
        cells: ``(nx, ny)``.
        spacing: ``(Δx, Δy)`` [m].
        nparts: Number of ranks.
    """
    nx, ny = cells
    path = reachable(z.reshape(ny, nx), (released > 0.0).reshape(ny, nx), spacing).ravel()
    if nparts < 2 or not path.any():
        return None
    start = released > 0.0
    origin = (float(centres[start, 0].mean()), float(centres[start, 1].mean()))
    pieces = strip_owners(centres[:, 0], centres[:, 1], path.astype(float),
                          PIECES_PER_RANK * nparts, origin)
    return (pieces % nparts).astype(np.int32)  # dealt in turn along the path


def cell_partitioner(owners: np.ndarray, nx: int) -> Callable:
    """Return a DOLFINx cell partitioner giving cell ``j nx + i`` to ``owners[j nx + i]``.

    Cells are located from their lowest vertex (``create_rectangle`` numbers the vertices
    column by column, ``i (ny + 1) + j``; a cell whose vertices do not fit raises). Each cell
    also goes, as a ghost, to the owners of the cells that share a facet with it (DOLFINx's
    ``shared_facet`` ghost mode).
    """
    from dolfinx.cpp.graph import AdjacencyList_int32

    ny = owners.size // nx

    def partition(comm, nparts, cell_types, cells) -> AdjacencyList_int32:
        topo = np.asarray(cells[0]).reshape(-1, 4)
        low = topo.min(axis=1)
        i, j = low // (ny + 1), low % (ny + 1)
        if topo.size and not np.array_equal(np.sort(topo - low[:, None], axis=1),
                                            np.tile([0, 1, ny + 1, ny + 2], (low.size, 1))):
            raise RuntimeError("create_rectangle numbered its vertices in an unknown order")
        own = owners[j * nx + i]
        ghosts = [np.where(ok, owners[np.clip(jn, 0, ny - 1) * nx + np.clip(in_, 0, nx - 1)],
                           own)
                  for in_, jn, ok in ((i - 1, j, i > 0), (i + 1, j, i < nx - 1),
                                      (i, j - 1, j > 0), (i, j + 1, j < ny - 1))]
        dest = [[int(o)] + sorted({int(g[k]) for g in ghosts} - {int(o)})
                for k, o in enumerate(own)]
        offsets = np.cumsum([0] + [len(d) for d in dest]).astype(np.int32)
        data = np.fromiter((r for d in dest for r in d), dtype=np.int32, count=int(offsets[-1]))
        return AdjacencyList_int32(data, offsets)

    return partition
