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

from fem_runout.active import RINGS, ActiveSet
from fem_runout.assembly import VectorAssembler
from fem_runout.mesh import Discretization, GhostReducer

__all__ = ["ActiveForms", "restrict"]

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


class ActiveForms(ActiveSet):
    """The active set with the transport forms' assemblers restricted to it.

    Args:
        disc: The discretization.
        reducer: Max/min over the ranks sharing a node.
        forms: The compiled forms over the whole mesh.
        rings: Node hops covered around the wet nodes (>= 2).
    """

    def __init__(self, disc: Discretization, reducer: GhostReducer, forms: list[fem.Form],
                 rings: int = RINGS) -> None:
        super().__init__(disc, reducer, rings)
        self.full = [VectorAssembler(f) for f in forms]
        #: the forms' assemblers on the active cells
        self.forms: list[VectorAssembler] = list(self.full)
        #: the first form (the predictor) on the active local cells, ghosts included
        self.predictor = self._ghosted(self.full[0])

    def _ghosted(self, predictor: VectorAssembler) -> VectorAssembler:
        """Return the cell-integral form on every active local cell, owned and ghosts."""
        kinds = [kind for kind, _, _ in predictor.integrals]
        if kinds != [IntegralType.cell]:
            raise ValueError("the predictor must have one cell integral")
        return predictor.restricted([self.cells.astype(np.int32)])

    def update(self, q: np.ndarray, nodes: np.ndarray | None = None) -> bool:
        """Rebuild the set and the assemblers if the flow nears the edge (collective)."""
        if not super().update(q, nodes):
            return False
        self.forms = [restrict(a, self.mask) for a in self.full]
        self.predictor = self._ghosted(self.full[0])
        return True
