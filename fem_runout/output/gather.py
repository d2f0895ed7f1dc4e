"""Gather nodal Q1 data to rank 0 in one global, rank-count independent order."""

from __future__ import annotations

from mpi4py import MPI  # before dolfinx

# isort: split

import numpy as np
from dolfinx import fem

from fem_runout.mesh import node_coordinates

__all__ = [
    "exact_global_sum", "gather_nodal", "global_max", "global_min", "global_sum",
    "sorted_node_order",
]

# Coordinates are rounded to this fraction of the domain extent before sorting, so that
# round-off cannot swap two nodes of the same grid row.
_SORT_TOLERANCE = 1e-9


def global_sum(comm: MPI.Comm, value: float) -> float:
    """Sum a local float over all ranks (collective).

    Args:
        comm: The communicator.
        value: This rank's contribution.

    Returns:
        The global sum, the same on every rank.
    """
    return float(comm.allreduce(float(value), op=MPI.SUM))


def exact_global_sum(comm: MPI.Comm, terms: np.ndarray) -> float:
    """Sum of every rank's terms with the same bits on any number of ranks (collective).

    :func:`fem_runout.exact_sum.exact_total` with the largest term and the number of terms
    reduced first (three reductions: for totals reported once, not for the step).

    Args:
        comm: The communicator.
        terms: This rank's terms (e.g. lumped mass times depth on the owned nodes).
    """
    from fem_runout.exact_sum import exact_total

    terms = np.asarray(terms, dtype=np.float64)
    bound = global_max(comm, float(np.max(np.abs(terms), initial=0.0)))
    count = int(comm.allreduce(int(terms.size), op=MPI.SUM))
    return exact_total(terms, bound, count, comm)


def global_max(comm: MPI.Comm, value: float) -> float:
    """Maximum of a local float over all ranks (collective).

    Args:
        comm: The communicator.
        value: This rank's value (use ``-inf`` for "nothing here").

    Returns:
        The global maximum, the same on every rank.
    """
    return float(comm.allreduce(float(value), op=MPI.MAX))


def global_min(comm: MPI.Comm, value: float) -> float:
    """Minimum of a local float over all ranks (collective).

    Args:
        comm: The communicator.
        value: This rank's value (use ``inf`` for "nothing here").

    Returns:
        The global minimum, the same on every rank.
    """
    return float(comm.allreduce(float(value), op=MPI.MIN))


def sorted_node_order(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Permutation that sorts nodes by ``(y, x)`` (rows of a structured grid, then columns).

    Coordinates are compared after rounding to ``1e-9`` of the domain extent, so that
    round-off cannot break the row structure.

    Args:
        x: Node x coordinates.
        y: Node y coordinates.

    Returns:
        Indices ``order`` such that ``x[order], y[order]`` is sorted by ``(y, x)``.
    """
    if x.size == 0:
        return np.zeros(0, dtype=np.int64)
    extent = max(float(np.ptp(x)), float(np.ptp(y)), 1.0) * _SORT_TOLERANCE
    kx = np.round((x - x.min()) / extent)
    ky = np.round((y - y.min()) / extent)
    return np.lexsort((kx, ky))


def _gatherv(comm: MPI.Comm, local: np.ndarray, counts: np.ndarray) -> np.ndarray | None:
    """Gather a float64 array with ``counts[r]`` rows per rank to rank 0."""
    trailing = local.shape[1:]
    width = int(np.prod(trailing)) if trailing else 1
    send = np.ascontiguousarray(local, dtype=np.float64).reshape(-1)
    if comm.rank == 0:
        recv = np.empty(int(counts.sum()) * width, dtype=np.float64)
        comm.Gatherv(send, (recv, counts * width), root=0)
        return recv.reshape((int(counts.sum()), *trailing))
    comm.Gatherv(send, None, root=0)
    return None


def gather_nodal(
    V: fem.FunctionSpace, arrays: dict[str, np.ndarray]
) -> dict[str, np.ndarray] | None:
    """Gather arrays on the owned Q1 nodes of every rank to rank 0, sorted by ``(y, x)``.

    Collective. The result does not depend on the number of ranks: nodes are put in one
    global order, sorted by ``y`` then ``x`` (so on a structured ``nx x ny`` grid, reshaping
    to ``(ny + 1, nx + 1)`` gives rows of constant ``y``).

    Args:
        V: The scalar Q1 space the arrays live on.
        arrays: Per-rank arrays on the owned dofs: each has at least
            ``V.dofmap.index_map.size_local`` entries along its first axis (extra entries,
            e.g. ghosts, are ignored). Values are converted to float64.

    Returns:
        On rank 0, a dict with ``'x'``, ``'y'`` (node coordinates) and every input array, all
        in the global order; ``None`` on the other ranks.

    Raises:
        ValueError: If an array is shorter than the number of owned dofs, or if an input
            array is named ``'x'`` or ``'y'``.
    """
    comm = V.mesh.comm
    n_owned = V.dofmap.index_map.size_local
    coords = node_coordinates(V)[:n_owned]
    local: dict[str, np.ndarray] = {"x": coords[:, 0], "y": coords[:, 1]}
    for name, values in arrays.items():
        if name in local:
            raise ValueError(f"array name {name!r} is reserved for coordinates")
        values = np.asarray(values)
        if values.shape[0] < n_owned:
            raise ValueError(f"array {name!r} has {values.shape[0]} entries < {n_owned} owned")
        local[name] = values[:n_owned]
    counts = np.asarray(comm.allgather(n_owned), dtype=np.int64)
    gathered = {name: _gatherv(comm, values, counts) for name, values in local.items()}
    if comm.rank != 0:
        return None
    order = sorted_node_order(gathered["x"], gathered["y"])
    return {name: values[order] for name, values in gathered.items()}
