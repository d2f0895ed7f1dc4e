"""The Q1 output fields of DAMPM, written from the global structured node array.

The solver works on the global node array (index ``j (nx + 1) + i``, :mod:`mpm.nodal`); the
outputs read DOLFINx functions on the rank's local dofs. :class:`FieldWriter` maps one to
the other and touches only the dofs written last time and now (the flow's window), so the
per-step cost follows the flow, not the mesh.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem

from mpm.nodal import NodalGrid

__all__ = ["FieldWriter"]


class FieldWriter:
    """The functions ``h, hu, hv, z`` on the shared Q1 space, written by global node.

    Args:
        V: The Q1 space.
        nodal: The global node numbering of the rank's dofs.
        z: Nodal elevation (local dofs, with ghosts).
    """

    def __init__(self, V: fem.FunctionSpace, nodal: NodalGrid, z: np.ndarray) -> None:
        self.fields = {k: fem.Function(V, name=k) for k in ("h", "hu", "hv", "z")}
        self.fields["z"].x.array[:] = z
        self._n_owned = nodal._n_owned
        self._local_of = np.full(nodal.n_nodes, -1, dtype=np.int64)  # global -> local dof
        self._local_of[nodal.node_index] = np.arange(nodal.node_index.size)
        self._written: dict[str, np.ndarray] = {}

    def owned_dofs(self, nodes: np.ndarray) -> np.ndarray:
        """Sorted owned dofs of the projection's global nodes (its support, any shape)."""
        local = self._local_of[nodes]
        return np.sort(local[(local >= 0) & (local < self._n_owned)])

    def write(self, name: str, nodes: np.ndarray, values: np.ndarray) -> None:
        """Set field ``name`` to ``values`` at the global ``nodes``, zero elsewhere.

        Owned and ghost dofs; only the dofs written last time and now are touched.
        """
        local = self._local_of[nodes]
        mine = local >= 0
        array = self.fields[name].x.array
        array[self._written.get(name, local[:0])] = 0.0
        array[local[mine]] = values[mine]
        self._written[name] = local[mine]
