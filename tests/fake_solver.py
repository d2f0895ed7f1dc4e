"""A stand-in for a Solver on a real Q1 mesh, for the output tests (serial and MPI)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import ufl
from dolfinx import fem, la, mesh


def fake_solver(comm, formulas, cells=(8, 4), size=(4.0, 2.0)):
    """Q1 fields ``h, hu, hv, z`` interpolated from formulas of ``(x, y)`` on a rectangle.

    Args:
        comm: Communicator.
        formulas: Mapping of field name to a function of (x, y).
        cells: (nx, ny).
        size: (lx, ly) of the rectangle [0, lx] × [0, ly].
    """
    msh = mesh.create_rectangle(comm, [[0.0, 0.0], list(size)], list(cells),
                                mesh.CellType.quadrilateral)
    V = fem.functionspace(msh, ("Lagrange", 1))
    fields = {}
    for name, formula in formulas.items():
        fields[name] = fem.Function(V, name=name)
        fields[name].interpolate(lambda x, f=formula: f(x[0], x[1]) + 0.0 * x[0])
    mass = fem.assemble_vector(fem.form(ufl.TestFunction(V) * ufl.dx))
    mass.scatter_reverse(la.InsertMode.add)
    mass.scatter_forward()
    n_owned = V.dofmap.index_map.size_local
    return SimpleNamespace(
        comm=comm, mesh=msh, V=V, fields=fields, lumped_mass=mass.array.copy(), outflow_volume=0.0,
        dried_volume=0.0,
        flow_dofs=lambda: np.arange(n_owned),
    )
