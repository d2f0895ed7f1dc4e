"""Where a run went bad: the location of a bad state, for any method.

The solvers' own ``health()`` says what is wrong (NaN, negative depth, a collapsed particle
column); the runner adds an exploding speed (``numerics.max_speed``), and :func:`locate` names
the place from the Q1 fields: the owned node with a non-finite value, else the most negative
depth, else the largest speed, with its coordinates.
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.callbacks import flow_index

__all__ = ["locate", "motion_terms", "reduce_flag", "state_flag"]


@numba.njit(cache=True)
def state_flag(h, hu, hv, n):
    """Health code of the first ``n`` nodes: 2 non-finite, 1 negative depth, 0 good.

    One pass over ``h, hu, hv`` without a copy (a step's check).
    """
    negative = False
    for i in range(n):
        a, b, c = h[i], hu[i], hv[i]
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c)):
            return 2
        negative = negative or a < 0.0
    return 1 if negative else 0


def reduce_flag(comm, flag: int, *also_max: np.ndarray | None) -> int:
    """Largest of the ranks' health flags (collective: one max reduction).

    Args:
        comm: The communicator.
        flag: This rank's flag (0: good; the solvers' codes otherwise).
        also_max: Float arrays maximised over the ranks in the same message, each in place
            (None skipped): the solver's step limits, the runner's largest speed and stop
            signal ride along with every step's check.
    """
    from mpi4py import MPI

    arrays = [a for a in also_max if a is not None]
    values = np.concatenate([[float(flag)], *(np.ravel(a) for a in arrays)])
    comm.Allreduce(MPI.IN_PLACE, values, op=MPI.MAX)
    start = 1
    for a in arrays:
        a[...] = values[start:start + a.size].reshape(a.shape)
        start += a.size
    return int(values[0])


def _badness(h: np.ndarray, hu: np.ndarray, hv: np.ndarray, depth: float) -> np.ndarray:
    """Per node: inf for non-finite values, -h for negative depths, else the speed."""
    with np.errstate(all="ignore"):
        speed = np.where(h > depth, np.sqrt(hu * hu + hv * hv) / np.where(h > depth, h, 1.0), 0)
        bad = np.where(h < 0, 1e300 - h, speed)
        return np.where(np.isfinite(h) & np.isfinite(hu) & np.isfinite(hv), bad, np.inf)


def locate(solver, depth: float) -> str:
    """Return ``" near (x, y)"`` for the worst owned node of the current fields (collective).

    Empty for a solver without Q1 fields (a test's scalar stand-in).
    """
    if not hasattr(solver, "fields") or not hasattr(solver, "V"):
        return ""
    idx = flow_index(solver)
    h, hu, hv = (solver.fields[k].x.array[idx].real for k in ("h", "hu", "hv"))
    bad = _badness(h, hu, hv, depth)
    local = (float(bad.max()), None) if bad.size else (-np.inf, None)
    if bad.size:
        k = int(np.argmax(bad))
        from fem_runout.mesh import node_coordinates

        xy = node_coordinates(solver.V)[np.arange(h.size)[k] if isinstance(idx, slice)
                                        else idx[k]]
        local = (local[0], (float(xy[0]), float(xy[1])))
    worst = max(solver.comm.allgather(local), key=lambda item: item[0])
    if worst[1] is None or worst[0] <= 0:
        return ""
    return f" near (x, y) = ({worst[1][0]:.6g}, {worst[1][1]:.6g})"


@numba.njit(cache=True)
def motion_terms(nodes, h, hu, hv, mass, depth, energy, terms):
    """Speed and kinetic-energy terms of the nodes deeper than ``depth`` (one pass).

    ``terms[:k] = m q² / h`` over those nodes (``k`` returned; none unless ``energy``) and
    the largest ``q² / h²``; both maxima as ``np.max`` (NaN wins). Returns ``(q²/h² max or
    -inf if no node is deeper, terms max or 0, k)``.
    """
    top, big, k = -np.inf, 0.0, 0
    for n in range(nodes.shape[0]):
        i = nodes[n]
        hi = h[i]
        if not hi > depth:
            continue
        q2 = hu[i] * hu[i] + hv[i] * hv[i]
        r = q2 / (hi * hi)
        if top == top and (r != r or r > top):  # np.max: the first NaN stays
            top = r
        if energy:
            t = mass[i] * q2 / hi
            terms[k] = t
            k += 1
            if big == big and (t != t or t > big):
                big = t
    return top, big, k
