"""The bed's curvature on unstructured meshes: exact for quadratic beds (issue 17).

The slope-consistent model's curvature term ``u·H·u`` (:mod:`fem_runout.physics.slope`)
needs the bed's Hessian ``H`` at the nodes: the lumped L2 projection ``L`` of the gradient of
the nodal gradient ``G = L(Z)``, ``L(f)_i = Σ_K ∫_K φ_i ∇f_h / m_i``. ``L`` is exact for a
linear ``f`` at every node. On a uniform grid it is also exact for a quadratic one away from
the sides (each node's patch is symmetric), so ``H`` is exact for a quadratic bed there. On an
unstructured mesh it is not: for a quadratic bed, exactly,

    L(Z)_i = ∇Z(x_i) + Σ_k H_k E_{k,i},

with ``E_{k,i} = L(q_k)_i`` the lumped gradient of the quadratic monomials centred at the node
(``q_k`` = ``(x-x_i)²/2``, ``(x-x_i)(y-y_i)``, ``(y-y_i)²/2``; their exact gradient vanishes
at ``x_i``; :func:`monomial_gradients`). The Hessian made from ``G`` then errs by O(1):
5–36 % of a paraboloid's curvature on a grid jittered by ±20 % of its cells, which made DAMPM's
avaKot run-out 2.6 % longer there than on the same grid unjittered (docs/meshes.md).

:func:`corrected_hessian` removes that error by defect correction: ``H⁰`` from ``G``, then
``H^{j+1}`` = the Hessian of ``G - H^j·E`` (``Σ_k H^j_k E_{k,i}`` per node), until the change
is below round-off. The exact Hessian of a quadratic bed is the fixed point at every node,
sides and corners included, and the iteration contracts (about a factor 1.8 per pass on a
jittered grid and on the avaKot corridor's gmsh mesh). Each pass uses the same wide stencil as
the grid's ``H``, so on a real DEM the result is as smooth as before (the iterates change
avaKot's corridor Hessian by 7 % RMS). On a uniform mesh ``E = 0`` inside and nothing changes;
the structured grid keeps ``H⁰`` (exact there). All sums are
:meth:`Discretization.cell_sum <fem_runout.mesh.Discretization.cell_sum>`'s and the stopping
test is a global maximum: the same bits on any partition.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI

__all__ = ["MAX_PASSES", "corrected_hessian", "monomial_gradients"]

#: Most correction passes (each two lumped projections, once at setup).
MAX_PASSES = 200
#: The passes stop when no entry changes by more than this times the scale ``max(|H|,
#: |G| / shortest edge)`` [1/m] (a plane's Hessian is round-off: its slope sets the scale).
TOLERANCE = 1e-13


def monomial_gradients(disc) -> np.ndarray:
    """(n_local, 3, 2) lumped gradients ``E_{k,i}`` of the node-centred quadratic monomials.

    ``E_{k,i} = Σ_K ∫_K φ_i ∇I_h q_k / m_i`` (``I_h``: the Q1 interpolant) with ``q_k`` =
    ``(x-x_i)²/2, (x-x_i)(y-y_i), (y-y_i)²/2``; zero inside a uniform grid.
    """
    n = disc.n_owned_cells
    x = disc.coords[disc.cell_nodes[:n]][..., :2]
    d = x[:, None, :, :] - x[:, :, None, :]  # (cells, a, b, 2): x_b - x_a
    dx, dy = d[..., 0], d[..., 1]
    q = np.stack([0.5 * dx * dx, dx * dy, 0.5 * dy * dy], axis=-1)
    per = np.einsum("nabd,nabk->nakd", disc.C[:n], q).reshape(n, 4, 6)
    return (disc.cell_sum(np.ascontiguousarray(per)) / disc.lumped_mass[:, None]).reshape(-1, 3, 2)


def corrected_hessian(disc, grad: np.ndarray,
                      hessian_of: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Return the bed's Hessian, exact for a quadratic bed on any mesh (collective).

    Args:
        disc: A :class:`fem_runout.mesh.Discretization`.
        grad: (n_local, 2) the lumped gradient ``G`` of the bed.
        hessian_of: The symmetrised lumped Hessian of a nodal gradient field, (n_local, 3)
            (:func:`fem_runout.physics.slope.lumped_hessian`; passed in, as slope.py
            imports this module).

    Returns:
        (n_local, 3) ``(H_xx, H_xy, H_yy)``; ``hessian_of(grad)`` if the passes diverge
        (a mesh too irregular for them; not met on the meshes tested).
    """
    e = monomial_gradients(disc)
    first = hess = hessian_of(grad)
    local = [np.abs(hess).max(initial=0.0),
             np.abs(grad).max(initial=0.0) / max(disc.min_cell_size, 1e-300)]
    scale = disc.comm.allreduce(float(max(local)), op=MPI.MAX)
    best = np.inf
    for _ in range(MAX_PASSES):
        new = hessian_of(grad - np.einsum("nk,nkd->nd", hess, e))
        change = disc.comm.allreduce(float(np.abs(new - hess).max(initial=0.0)), op=MPI.MAX)
        if not change <= 2.0 * best:  # diverging (or NaN): keep the plain Hessian
            return first
        hess, best = new, min(best, change)
        if change <= TOLERANCE * scale:
            break
    return hess
