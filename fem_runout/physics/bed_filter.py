"""The bed's curvature at a physical length scale: heat flow of the bed before its Hessian.

The slope-consistent model's centrifugal term ``u·H·u`` (:mod:`fem_runout.physics.slope`)
takes the bed's Hessian ``H`` from the nodal bed. On a DEM that Hessian holds the terrain's
roughness down to the pixel: at 50 m/s a bump of 30 m radius has ``|u·H·u| ≈ 8 g``, so ``G =
cos²θ max(g + u·H·u, 0)`` and the friction's normal stress switch off and on over a few
cells. A depth-averaged flow cannot follow the bed at scales below its own (the model assumes
``h |H| ≪ 1`` and a bed that varies slowly along the flow), and those pixel-scale values make
the result depend on where the mesh's nodes sample the DEM: half a pixel of shift moved
DAMPM's avaKot footprint by 12 % (docs/meshes.md).

:func:`heat_smoothed` returns the bed after heat flow ``∂_t Z = ∇²Z`` over ``t = ℓ²/2``:
Gaussian smoothing of standard deviation ``ℓ`` per axis (``model.curvature_scale``), by
explicit steps of the lumped Q1 heat equation ``Z ← Z - τ M_L^{-1} K Z`` (natural boundary
condition). The result depends on ``ℓ``, not on the cells: the same scale on the grid and on
a gmsh mesh of the same terrain. Only ``H`` is taken from it; the bed, its gradient and the
lake at rest keep the unsmoothed nodes. A quadratic bed keeps its Hessian exactly away from
the sides (heat flow adds a constant to it).
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from fem_runout.mesh import physical_basis

__all__ = ["element_stiffness", "heat_smoothed", "heat_steps"]


def element_stiffness(xc: np.ndarray) -> np.ndarray:
    """(n_cells, 4, 4) element stiffness ``∫_K ∇φ_a·∇φ_b`` of bilinear cells.

    Args:
        xc: (n_cells, 4, 2) node coordinates in the Q1 reference order.
    """
    _, grad, w = physical_basis(xc)
    stiff = np.einsum("cq,cqia,cqja->cij", w, grad, grad)
    return 0.5 * (stiff + stiff.transpose(0, 2, 1))


def heat_steps(disc, stiffness: np.ndarray, scale: float) -> tuple[int, float]:
    """``(n, τ)``: explicit steps of the lumped heat equation reaching ``t = scale²/2``.

    ``τ`` is at most ``1 / ρ`` with ``ρ`` Gershgorin's bound of ``M_L^{-1} K`` (the largest
    ``Σ_K Σ_b |K_ab| / m_a`` over the nodes, a global maximum): every mode decays
    monotonically (amplification ``1 - τλ ∈ [0, 1]``), so no step overshoots.
    """
    row = disc.cell_sum(np.ascontiguousarray(np.abs(stiffness).sum(axis=2)))
    rho = disc.comm.allreduce(float(np.max(row / disc.lumped_mass, initial=0.0)), op=MPI.MAX)
    total = 0.5 * scale * scale
    if rho <= 0.0:
        return 0, 0.0
    steps = max(1, math.ceil(total * rho))
    return steps, total / steps


def heat_smoothed(disc, z: np.ndarray, scale: float) -> np.ndarray:
    """Return the nodal bed after heat flow over ``scale²/2`` (module docstring; collective).

    Args:
        disc: A :class:`fem_runout.mesh.Discretization`.
        z: Nodal bed (local, ghosts included).
        scale: Standard deviation ``ℓ`` of the equivalent Gaussian [m].

    Returns:
        (n_local,) smoothed bed, ghosts included; the same bits on any partition (the
        sums are :meth:`Discretization.cell_sum <fem_runout.mesh.Discretization.cell_sum>`'s).
    """
    n = disc.n_owned_cells
    cells = disc.cell_nodes[:n]
    stiffness = element_stiffness(disc.coords[cells][..., :2])
    steps, tau = heat_steps(disc, stiffness, scale)
    out = np.array(z, dtype=float)
    for _ in range(steps):
        flux = np.einsum("cab,cb->ca", stiffness, out[cells])
        out -= tau * disc.cell_sum(np.ascontiguousarray(flux)) / disc.lumped_mass
    return out
