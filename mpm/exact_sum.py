"""Order-independent particle-to-grid sums: the same bits on any number of ranks.

DAMPM sums every particle's contribution into the nodes and then over the ranks. A floating
point sum depends on its order, and the order depends on which particles a rank holds, so
1, 2 and 3 ranks used to differ by up to 1e-7 (relative L1 of h, Stoker 100:1). Here each
contribution ``x`` is split into two *folds* (pre-rounded summation, Demmel & Nguyen 2015,
"Parallel reproducible summation", IEEE TC 64(7)):

    hi = (x + M_1) - M_1,    lo = ((x - hi) + M_2) - M_2,    M_f = 1.5 · 2^{e_f},

so that ``hi`` is a multiple of ``ulp(M_1)`` and ``lo`` of ``ulp(M_2)``. With ``2^{e_1} >=
N max|x|`` (``N`` the number of particles, ``max|x|`` a bound on any contribution of the
column), every partial sum of the ``hi`` and of the ``lo`` is exact in floating point, in
any order and over any split between ranks; the node's value is ``Σ hi + Σ lo``. What the two
folds drop is below ``2^{-105} N² max|x|`` (4e-22 max|x| for 1e5 particles). The exponents
come from a max and a count (exact, the same on every rank).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

__all__ = ["extractors"]


def extractors(bounds: np.ndarray, n_terms: int, comm: MPI.Comm) -> np.ndarray:
    """Extractors ``M_f`` per column, (n_columns, 2) (collective: one max reduction).

    Args:
        bounds: Local bound of ``|x|`` per column (any contribution on this rank).
        n_terms: Largest number of contributions any node gets, over all ranks (the global
            particle count is one).
        comm: Communicator.
    """
    local = np.nan_to_num(np.asarray(bounds, dtype=np.float64), nan=np.inf, posinf=1e300)
    glob = np.empty_like(local)
    comm.Allreduce(local, glob, op=MPI.MAX)
    nb = max(int(n_terms), 1).bit_length()
    e_b = np.frexp(glob)[1].astype(np.int64)  # |x| < 2^e_b
    e1 = e_b + nb
    e2 = e1 - 52 + nb
    return np.stack([np.ldexp(1.5, e1), np.ldexp(1.5, e2)], axis=1)
