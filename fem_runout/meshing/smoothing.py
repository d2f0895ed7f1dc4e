"""Size-equalising smoothing of an outline's quadrilateral mesh (``domain.smoothing``).

gmsh's quadrilaterals (Frontal-Delaunay for quads, Blossom full-quad recombination) come with
scattered small cells where the recombination left a defect: on a disc meshed at 0.5 m, 1 %
of the cells have a crossing length (``sqrt(2) |K| / d_max``, the length the time steps of
both methods follow) below 0.43 of the asked size and the smallest 0.33. Those few cells set
the time step of the whole run, and their jump in size from their neighbours costs accuracy
(docs/meshes.md, "The mesh's smoothing").

Each pass moves every interior node to the weighted mean of the centres of its cells, with
weight ``w_K = |K| / T_K``: a cell larger than its target pulls the node towards it, a smaller
one lets it go, so small cells grow and large ones shrink until the sizes follow the targets.
The target ``T_K`` is the initial area averaged over the cell's neighbourhood (eight rings), so
a graded mesh keeps its grading and only the cell-to-cell scatter is smoothed out. Boundary
nodes stay where they are (the mesh still covers the outline exactly). A pass never gives a
corner a sine below 0.5 (sharper than 30 or wider than 150 degrees; or below the input's worst,
if that is lower): the nodes of any cell that would get one are put back (until none would).
The passes are vectorised numpy in a fixed order: the same mesh bit for bit.
"""

from __future__ import annotations

import numpy as np

from fem_runout.meshing.quadmesh import corner_sines, quad_areas

__all__ = ["equalize_sizes"]

#: Passes averaging the initial areas into the targets (each over the cells at a node): wide
#: enough that a defect's own deficit hardly lowers its target (2 rings kept a third of the
#: gain on a uniform disc, 8 keep most of it), narrow against a grading of 5 to 10 m over
#: 200 m (the finest cells of avaKot's corridor grow by 4 % on average).
TARGET_RINGS = 8
#: Smallest corner sine a pass may make (30 or 150 deg), or the input's smallest if lower.
SINE_FLOOR = 0.5


def _node_mean(quads: np.ndarray, values: np.ndarray, n_nodes: int) -> np.ndarray:
    """Mean over the cells at each node of per-cell ``values`` (nodes without cells: 0)."""
    total = np.zeros(n_nodes)
    count = np.zeros(n_nodes)
    for k in range(4):
        np.add.at(total, quads[:, k], values)
        np.add.at(count, quads[:, k], 1.0)
    return total / np.where(count > 0.0, count, 1.0)


def _targets(nodes: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Target area of every cell: the initial areas averaged over :data:`TARGET_RINGS` rings."""
    cell = quad_areas(nodes, quads)
    for _ in range(TARGET_RINGS):
        cell = _node_mean(quads, cell, len(nodes))[quads].mean(axis=1)
    return cell


def _one_pass(nodes: np.ndarray, quads: np.ndarray, target: np.ndarray, fixed: np.ndarray,
              floor: float) -> np.ndarray:
    """One Jacobi pass of the weighted centre averaging; returns the new node coordinates."""
    area = quad_areas(nodes, quads)
    weight = area / target
    centre = nodes[quads].mean(axis=1)
    num = np.zeros(nodes.shape)
    den = np.zeros(len(nodes))
    for k in range(4):
        np.add.at(num, quads[:, k], weight[:, None] * centre)
        np.add.at(den, quads[:, k], weight)
    new = nodes.copy()
    move = ~fixed & (den > 0.0)
    new[move] = num[move] / den[move, None]
    while True:  # put back the nodes of cells that would get a sharper corner than allowed
        bad = corner_sines(new[quads]).min(axis=1) < floor
        if not bad.any():
            return new
        back = np.zeros(len(nodes), dtype=bool)
        back[quads[bad].ravel()] = True
        back &= np.any(new != nodes, axis=1)
        if not back.any():  # only cells that were already there: nothing left to undo
            return new
        new[back] = nodes[back]


def equalize_sizes(nodes: np.ndarray, quads: np.ndarray, boundary: np.ndarray,
                   passes: int) -> np.ndarray:
    """Return the node coordinates after ``passes`` size-equalising passes (module docstring).

    Args:
        nodes: ``(N, 2)`` coordinates.
        quads: ``(M, 4)`` node indices, counterclockwise, convex.
        boundary: Indices of the nodes that stay (the boundary's,
            :meth:`fem_runout.meshing.quadmesh.QuadMesh.boundary_nodes`).
        passes: Number of passes (0: the nodes unchanged).

    Returns:
        ``(N, 2)`` new coordinates; boundary nodes unchanged, every cell convex with no corner
        sine below :data:`SINE_FLOOR` or the input's smallest.
    """
    nodes = np.array(nodes, dtype=np.float64)
    if passes <= 0 or not len(quads):
        return nodes
    quads = np.asarray(quads, dtype=np.int64)
    target = _targets(nodes, quads)
    fixed = np.zeros(len(nodes), dtype=bool)
    fixed[np.asarray(boundary, dtype=np.int64)] = True
    floor = min(SINE_FLOOR, float(corner_sines(nodes[quads]).min()))
    for _ in range(passes):
        nodes = _one_pass(nodes, quads, target, fixed, floor)
    return nodes
