"""Domain weights of particles at rest, taken from the step before (issue 17).

On a gmsh mesh a particle's weights (:func:`mpm.mesh_weights.domain_basis`) depend on its
cell, its reference coordinates and its domain's eight corner offsets, and on nothing else
that changes. A particle whose eleven numbers have the bits of the same particle (by id) in
the last call gets that call's entries copied: the same bits as computing them, at the cost
of a copy. On the avaKot corridor 16 % of the particle-steps are such particles at
rest (docs/meshes.md, "Session 54").
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["KEY_WIDTH", "NO_PREVIOUS", "SEARCH", "PreviousWeights", "copy_entries", "write_keys"]


#: Keys per particle: the cell, the bits of ``ξ, η`` and of the domain's eight offsets (and,
#: in the column after them, the particle's id, to find it in the next call).
KEY_WIDTH = 11


#: How far ahead of the last match the last call's particles are searched for a particle's id.
SEARCH = 64


@numba.njit(cache=True, inline="always")
def write_keys(keys, record, p, k, ixi, ieta, iquad, ident, pkeys, n_prev, cursor):
    """Write particle ``p``'s keys (if ``record``); find it in the last call's keys.

    The last call's particle with id ``ident`` is looked for from ``cursor`` on, at most
    :data:`SEARCH` places ahead: between two steps particles leave (the rest keep their
    order) and arrive at the end, so a particle is found where the last one was, or a few
    places further. Returns ``(index, cursor)``: the last call's index of a particle with the
    same keys (-1: none) and the next search's start.
    """
    if record:
        keys[p, 0], keys[p, 1], keys[p, 2] = k, ixi, ieta
        for c in range(8):
            keys[p, 3 + c] = iquad[c]
        keys[p, KEY_WIDTH] = ident
    for q in range(cursor, min(cursor + SEARCH, n_prev)):
        if pkeys[q, KEY_WIDTH] == ident:
            same = pkeys[q, 0] == k and pkeys[q, 1] == ixi and pkeys[q, 2] == ieta
            for c in range(8):
                same = same and pkeys[q, 3 + c] == iquad[c]
            return (q if same else -1), q + 1
    return -1, cursor


@numba.njit(cache=True, inline="always")
def copy_entries(src, dst, count, pnodes, pS, pdS, prel, nodes, S, dS, rel):
    """Copy ``count`` entries from ``src`` in the last call's buffers to ``dst``."""
    for e in range(count):
        nodes[dst + e], S[dst + e] = pnodes[src + e], pS[src + e]
        dS[dst + e, 0], dS[dst + e, 1] = pdS[src + e, 0], pdS[src + e, 1]
        rel[dst + e, 0], rel[dst + e, 1] = prel[src + e, 0], prel[src + e, 1]


#: ``previous`` of a call without a last call (nothing to reuse, nothing recorded).
NO_PREVIOUS = (np.empty((0, KEY_WIDTH + 1), np.int64), 0, np.empty((0, KEY_WIDTH + 1), np.int64),
                np.zeros(1, np.int64), np.empty(0, np.int64), np.empty(0), np.empty((0, 2)),
                np.empty((0, 2)))


class PreviousWeights:
    """The last call's keys and entries, and room for this call's keys.

    For :func:`mpm.mesh_weights.domain_basis`.

    The caller keeps one between calls and, after each successful call, hands it the entries
    it returned (:meth:`keep`); those buffers must stay untouched until the next call is done
    (a caller alternates two sets of buffers).
    """

    def __init__(self) -> None:
        self.keys = np.empty((0, KEY_WIDTH + 1), np.int64)
        self.next_keys = np.empty((0, KEY_WIDTH + 1), np.int64)
        self.count = 0
        self.entries: tuple[np.ndarray, ...] = NO_PREVIOUS[3:]

    def loop_arguments(self, n: int) -> tuple:
        """Arguments of the loop for ``n`` particles (grows this call's key array)."""
        if self.next_keys.shape[0] < n:
            self.next_keys = np.empty((2 * n, KEY_WIDTH + 1), np.int64)
        return (self.next_keys, self.count, self.keys, *self.entries)

    def keep(self, n: int, offsets: np.ndarray, *entries: np.ndarray) -> None:
        """Make the call just done (``n`` particles, its ``offsets`` and entries) the last one."""
        self.keys, self.next_keys = self.next_keys, self.keys
        self.count = n
        self.entries = (offsets, *entries)
