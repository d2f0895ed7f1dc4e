"""Partition-independent nodal sums of cell contributions (bitwise the same on any rank count).

A nodal sum ``Σ_K c[K, a]`` over the cells around a node is computed by DOLFINx (and by a
plain loop) in the order in which the cells happen to be stored and then across ranks in the
order of the ghost exchange: both depend on the partition, so 1, 2 and 3 ranks differ in the
last bit, and a flow that amplifies round-off (a moving shoreline, a splash) ends up
measurably different (Thacker's bowl after two periods: 1.6e-3 between 1 and 2 ranks).

Here every contribution goes to its own *slot*: on a structured quadrilateral mesh each node
is the lower-left, lower-right, upper-left or upper-right corner of at most one cell, so the
slot ``s = 2 [y_node > y_centre] + [x_node > x_centre]`` is unique per node. Slots are filled
by exactly one owned cell over all ranks, the cross-rank exchange adds zeros (exact), and the
four slots are summed in a fixed order: the result depends on the values only. On an
unstructured mesh the slot of a cell at a node is the rank of the cell's input index among the
node's cells (:func:`fem_runout.quadmesh.cell_slots`), with as many slots as the largest
number of cells around a node.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["cell_slots", "gather_on", "gather_total", "sources", "total_on"]


def cell_slots(xc: np.ndarray) -> np.ndarray:
    """Corner index (0..3) of every node of every cell, from the node coordinates.

    Args:
        xc: (n_cells, 4, 2) node coordinates.

    Returns:
        (n_cells, 4) int64 slot per cell node.

    Raises:
        ValueError: If a cell has two nodes in the same corner (not a structured cell).
    """
    centre = xc.mean(axis=1, keepdims=True)
    slot = (2 * (xc[..., 1] > centre[..., 1]) + (xc[..., 0] > centre[..., 0])).astype(np.int64)
    if xc.shape[0] and not np.all(np.sort(slot, axis=1) == np.arange(4)):
        raise ValueError("cell nodes do not occupy four distinct corners")
    return slot


def sources(cells: np.ndarray, slot: np.ndarray, n_nodes: int, n_slots: int = 4) -> np.ndarray:
    """``src[i, s]`` = flat index ``4 K + a`` of the cell node filling slot ``s`` of node ``i``.

    -1 where no cell of ``cells`` fills the slot. ``n_slots`` is 4 on a structured mesh, the
    largest number of cells around a node on an unstructured one (:mod:`fem_runout.quadmesh`).
    """
    src = np.full((n_nodes, n_slots), -1, dtype=np.int64)
    src[cells.ravel(), slot.ravel()] = np.arange(cells.size, dtype=np.int64)
    return src


@numba.njit(cache=True)
def gather_total(src, flat, out):
    """:func:`gather_on` then :func:`total_on` without the buffer (one rank).

    ``out[k]`` from the slots ``src[k]``: all nodes, or the rows of a subset
    (:mod:`fem_runout.active`). A missing slot is skipped instead of adding 0.0: the same
    bits, since the running sum starts at +0.0 and never becomes -0.0 (x + 0.0 = x for every
    other x, NaN included).
    """
    if src.shape[1] == 4:  # the structured mesh: four slots unrolled, 2-3 times faster
        _gather_total4(src, flat, out)
        return
    for i in range(src.shape[0]):
        for c in range(flat.shape[1]):
            acc = 0.0
            for s in range(src.shape[1]):
                j = src[i, s]
                acc = acc + (flat[j, c] if j >= 0 else 0.0)
            out[i, c] = acc


@numba.njit(cache=True)
def _gather_total4(src, flat, out):
    """:func:`gather_total` with four slots, the slot indices read once per node."""
    for i in range(src.shape[0]):
        j0, j1, j2, j3 = src[i, 0], src[i, 1], src[i, 2], src[i, 3]
        for c in range(flat.shape[1]):
            acc = 0.0
            if j0 >= 0:
                acc = acc + flat[j0, c]
            if j1 >= 0:
                acc = acc + flat[j1, c]
            if j2 >= 0:
                acc = acc + flat[j2, c]
            if j3 >= 0:
                acc = acc + flat[j3, c]
            out[i, c] = acc


@numba.njit(cache=True)
def gather_on(src, flat, nodes, buf):
    """``buf[nodes[k], s, c] = flat[src[k, s], c]`` (0 where ``src`` is -1): the slots."""
    for k in range(nodes.shape[0]):
        i = nodes[k]
        for s in range(src.shape[1]):
            j = src[k, s]
            for c in range(flat.shape[1]):
                buf[i, s, c] = flat[j, c] if j >= 0 else 0.0


@numba.njit(cache=True)
def total_on(buf, nodes, out):
    """``out[k, c] = ((b[0, c] + b[1, c]) + b[2, c]) + ...`` for ``b = buf[nodes[k]]``."""
    for k in range(nodes.shape[0]):
        i = nodes[k]
        for c in range(buf.shape[2]):
            acc = buf[i, 0, c]
            for s in range(1, buf.shape[1]):
                acc = acc + buf[i, s, c]
            out[k, c] = acc
