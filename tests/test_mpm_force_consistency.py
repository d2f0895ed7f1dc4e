"""DAMPM's particle quadrature of the forces (seed eq. 34) against exact integrals.

At t = 0 on Thacker's bowl (a planar surface over a paraboloid) the nodal force sums
``f_i = Σ_p [-m_p g ∇Z(x_p) S_ip + V_p ½ ρ g h_p ∇S_ip]`` approximate
``∫ (-ρ g h ∇Z φ_i + ½ ρ g h² ∇φ_i) dx``. On the structured grid the sub-cell particles'
midpoint errors cancel between neighbours and the nodal forces converge at second order
(measured 1.7-1.9). On irregular cells they do not cancel: the same sums keep a relative error
of about 2 % at every resolution (docs/meshes.md, "DAMPM on a gmsh mesh"), which is why
DAMPM's Thacker error does not converge on gmsh meshes.
"""

import math

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI

from fem_runout.config import load_case
from fem_runout.methods import get, method_names
from fem_runout.references import thacker as ref

METHOD = next(m for m in method_names() if get(m).particles)


def _exact(solver) -> np.ndarray:
    """(n_local, 2) exact nodal forces of the initial state (degree-12 quadrature)."""
    V = solver.disc.V
    x = ufl.SpatialCoordinate(V.mesh)
    X, Y = x[0] - ref.L / 2, x[1] - ref.L / 2
    z = -ref.H0 * (1 - (X**2 + Y**2) / ref.A**2)
    h = ufl.max_value(ref.ETA * ref.H0 / ref.A**2 * (2 * X - ref.ETA) - z, 0)
    v = ufl.TestFunction(V)
    dx = ufl.dx(metadata={"quadrature_degree": 12})
    rho, g = solver.rho, solver.g
    out = []
    for k in range(2):
        b = fem.assemble_vector(fem.form((-rho * g * h * z.dx(k) * v
                                          + 0.5 * rho * g * h * h * v.dx(k)) * dx))
        b.scatter_reverse(la.InsertMode.add)
        out.append(b.array.copy())
    return np.stack(out, axis=1)


def _force_error(n: int) -> float:
    """Relative L2 error of the nodal forces 3 cells inside the wet disc."""
    solver = get(METHOD).build(load_case(ref.case_dict(n), [("method", METHOD)]),
                               MPI.COMM_SELF)
    nodal, sums, owned = solver.nodal, solver._sums, solver.disc.n_owned_nodes
    num = np.zeros((nodal.n_nodes, 2))
    num[sums.act] = sums.g[:, 3:5]
    num = num[nodal.node_index[:owned]]
    exact = _exact(solver)[:owned]
    xy = solver.disc.coords[:owned, :2]
    inner = np.hypot(xy[:, 0] - ref.L / 2 - ref.ETA, xy[:, 1] - ref.L / 2) < (
        ref.A - 3 * ref.L / n)
    return float(np.linalg.norm(num[inner] - exact[inner]) / np.linalg.norm(exact[inner]))


def test_initial_forces_converge_at_second_order_on_the_grid():
    errors = [_force_error(n) for n in (25, 50, 100)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert min(orders) > 1.6, (errors, orders)  # a second-order quadrature, with margin
