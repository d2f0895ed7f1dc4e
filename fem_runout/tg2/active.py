"""The active set of TG2-PC's assembly: the cells near the flow (issue 16).

Every term of the predictor and corrector forms (:mod:`fem_runout.tg2.forms`) carries a
factor ``h`` or ``q``: ``∇·q``, ``q⊗u``, ``g h ∇η``, the edge fluctuation ``g h̄ [η]`` and the
open-side ``g h ∂Z/∂n``. A cell whose nodes are all exactly dry has a zero predictor, and a
cell whose nodes and whose neighbours' nodes are all dry has zero corrector terms: leaving
them out of the assembly gives the same bits. The active cells are those with a node within
``rings`` node hops of a node where ``(h, hu, hv) ≠ 0``; the forms are assembled by the
numba :class:`~fem_runout.assembly.VectorAssembler` with the run's compiled FFCx kernels on
those cells and their facets (no JIT, no per-call DOLFINx overhead). A step needs the wet nodes'
cells and one ring; the set is rebuilt (collectively) when a wet node leaves the inner
``rings - 1`` hops, so a rebuild happens about every ``rings - 1`` rings the flow advances,
not every step.

Hops are grown node-wise with a max over the cells around each node and a max over the ranks
sharing it, so every rank agrees on the status of the cells it shares.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx.fem import IntegralType
from mpi4py import MPI

from fem_runout.assembly import VectorAssembler
from fem_runout.mesh import Discretization, GhostReducer

__all__ = ["ActiveForms", "restrict"]

#: Node hops around the wet nodes that the active set covers.
RINGS = 4


def restrict(assembler: VectorAssembler, active: np.ndarray) -> VectorAssembler:
    """Return ``assembler`` on the active cells: cell integrals, facets touching an active cell.

    The kernels, coefficients and constants are the form's; only the integration entities
    change, filtered in their original order.

    Args:
        assembler: The form's assembler over the whole mesh.
        active: (n_cells_local,) bool per local cell.
    """
    return assembler.restricted([_keep(kind, ents, active)
                                 for kind, _, ents in assembler.integrals])


def _keep(kind: IntegralType, entities: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Return the integration entities of ``kind`` that touch an active cell."""
    if kind == IntegralType.cell:
        out = entities[active[entities]]
    elif kind == IntegralType.interior_facet:
        pairs = entities.reshape(-1, 4)
        out = pairs[active[pairs[:, 0]] | active[pairs[:, 2]]]
    else:
        pairs = entities.reshape(-1, 2)
        out = pairs[active[pairs[:, 0]]]
    return np.ascontiguousarray(out.ravel(), dtype=np.int32)


class ActiveForms:
    """Forms assembled on the cells near the flow only; rebuilt when the flow moves on.

    Args:
        disc: The discretization.
        reducer: Max/min over the ranks sharing a node.
        forms: The compiled forms over the whole mesh.
        rings: Node hops covered around the wet nodes (>= 2).
    """

    def __init__(self, disc: Discretization, reducer: GhostReducer, forms: list[fem.Form],
                 rings: int = RINGS) -> None:
        if rings < 2:
            raise ValueError("the active set needs at least 2 rings")
        self.disc, self.reducer, self.rings = disc, reducer, rings
        self.full = [VectorAssembler(f) for f in forms]
        #: the forms' assemblers on the active cells
        self.forms: list[VectorAssembler] = list(self.full)
        self.inner: np.ndarray | None = None  # nodes within rings - 1 hops of the wet ones
        self.active_cells = disc.cell_nodes.shape[0]
        #: indices of the active owned cells (the cells the numba kernels visit)
        self.owned = np.arange(disc.n_owned_cells)
        self.rebuilds = 0

    def update(self, q: np.ndarray) -> list[VectorAssembler]:
        """Return the forms' assemblers for the state ``q`` (n_nodes_local, 3) (collective)."""
        wet = np.any(q != 0.0, axis=1)
        inside = self.inner is not None and bool(np.all(self.inner[wet]))
        if self.disc.comm.allreduce(inside, op=MPI.LAND):
            return self.forms
        hops = [wet.astype(np.float64)]
        for _ in range(self.rings):
            hops.append(self._grow(hops[-1]))
        self.inner = hops[-2] > 0.0
        active = hops[-1][self.disc.cell_nodes].max(axis=1) > 0.0
        self.forms = [restrict(a, active) for a in self.full]
        self.active_cells = int(active.sum())
        self.owned = np.flatnonzero(active[: self.disc.n_owned_cells])
        self.rebuilds += 1
        return self.forms

    def _grow(self, flag: np.ndarray) -> np.ndarray:
        """One node hop: the max over the cells around each node, then over the ranks."""
        cells = self.disc.cell_nodes
        out = flag.copy()
        np.maximum.at(out, cells, flag[cells].max(axis=1)[:, None])
        self.reducer.reduce(out, "max")
        return out
