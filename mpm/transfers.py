"""The particle ↔ grid kernels of a background grid, as one table.

The rectangle's grid uses the factored GIMP kernels (:mod:`mpm.kernels`, :mod:`mpm.forces`);
a gmsh mesh the point-basis kernels of :mod:`mpm.mesh_kernels`. Both take the grid's basis
arrays first and return the same things, so the solver calls ``grid.transfers.p2g(...)``
whatever the mesh.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

from mpm import forces, kernels, mesh_kernels

__all__ = ["GIMP", "POINT", "Transfers"]


class Transfers(NamedTuple):
    """Kernels of one basis: P2G, MUSL momentum, G2P, gradient, interpolation, forces, bounds."""

    p2g: Callable
    p2g_momentum: Callable
    g2p_flip: Callable
    g2p_gradient: Callable
    interpolate: Callable
    particle_forces: Callable
    transfer_bounds: Callable


#: The rectangle's factored GIMP kernels.
GIMP = Transfers(kernels.p2g, kernels.p2g_momentum, kernels.g2p_flip, kernels.g2p_gradient,
                 kernels.gimp_interpolate, forces.particle_forces, forces.transfer_bounds)
#: The point Q1 basis on any quadrilateral mesh.
POINT = Transfers(mesh_kernels.p2g, mesh_kernels.p2g_momentum, mesh_kernels.g2p_flip,
                  mesh_kernels.g2p_gradient, mesh_kernels.interpolate,
                  mesh_kernels.particle_forces, mesh_kernels.transfer_bounds)
