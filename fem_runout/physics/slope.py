"""Slope-consistent gravity and bed frame in horizontal coordinates (both methods share it).

The seed's eq. 1 drives and spreads the flow with the full ``g``: in horizontal coordinates
with the vertical depth ``h`` that is right for a lake, but on a 35° slope a thin flowing
layer feels gravity along the bed, ``g sinθ``, and a bed-normal stress ``ρ g cosθ h_n`` on a
normal thickness ``h_n = h cosθ``. The slope-consistent form used here is the Cartesian model
of Denlinger & Iverson (2004, J. Geophys. Res. 109) in the reduced form of Juez, Murillo &
García-Navarro (2013, J. Comput. Phys. 255) and Yuan et al. (2018, arXiv 1602.03299): the
material follows the bed ``z = Z(x, y)``, so its vertical acceleration is
``Dw/Dt = ∇Z·Du/Dt + u·H·u`` (``w = u·∇Z``, ``H`` the Hessian of ``Z``), and eliminating the
bed-normal reaction from the three momentum equations gives the horizontal momentum

    ∂_t(h u) + ∇·(h u ⊗ u) = -G h ∇(h + Z) + friction,   G = cos²θ max(g + u·H·u, 0),

with ``cos²θ = 1 / (1 + |∇Z|²)``. ``G`` replaces ``g`` in the seed's ``g h ∇η``, so a lake at
rest (``∇η = 0``) stays exact. On a plane it gives the along-slope acceleration
``g (sinθ - μ cosθ)`` of a block and the energy line (the bed reaction does no work:
``½|U|² + g Z`` is conserved without friction, ``|U|² = |u|² + (u·∇Z)²`` the speed along the
bed), and ``g + u·H·u`` is the bed-normal acceleration of a flow following a curved bed
(clipped at 0 where it would leave a convex edge: no horizontal pull, it flies on). The
pressure part is ``cos²θ`` smaller than the seed's across and along the slope; a bed-aligned
Savage–Hutter model has ``cos⁴θ`` along the slope (and no horizontal lake at rest), see
docs/method.md.

Friction (:mod:`fem_runout.physics.friction`) acts on the bed with the slope-normal thickness
``h_n = h cosθ`` and the speed along the bed ``|U|``; the bed-normal stress per unit mass is
``g cosθ`` (with ``curvature``: ``cosθ max(g + u·H·u, 0)``, the centrifugal term of
com1DFA and RAMMS). :class:`BedFrame` carries what the laws need per node.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from fem_runout.physics.bed_filter import heat_smoothed
from fem_runout.physics.recovery import corrected_hessian

__all__ = ["BedFrame", "SlopeGeometry", "downhill", "lumped_gradient", "lumped_hessian",
           "nodal_gradient", "slope_geometry"]


@dataclass(frozen=True)
class BedFrame:
    """The bed under each node, for friction laws in the slope-consistent form.

    Attributes:
        grad: (n, 2) bed gradient ``∇Z``.
        cos: (n,) ``cosθ = 1/sqrt(1 + |∇Z|²)``.
        normal: (n,) bed-normal stress per unit mass and normal thickness [m/s²]:
            ``g cosθ`` (or with the curvature term).
    """

    grad: np.ndarray
    cos: np.ndarray
    normal: np.ndarray
    #: the geometry this frame's ``grad`` belongs to (it keeps :func:`downhill` once formed)
    geometry: SlopeGeometry | None = None

    def take(self, nodes: np.ndarray) -> BedFrame:
        """Return the frame of a subset of the nodes (indices)."""
        return BedFrame(self.grad[nodes], self.cos[nodes], np.asarray(self.normal)[nodes])

    def downhill(self) -> np.ndarray:
        """(n, 2) horizontal unit vectors straight down the bed (:func:`downhill`)."""
        return downhill(self.grad) if self.geometry is None else self.geometry.downhill()

    def stretch(self, nx: np.ndarray, ny: np.ndarray) -> np.ndarray:
        """``|U|/|u| = sqrt(1 + (n·∇Z)²)`` for the horizontal direction ``n`` of motion."""
        along = nx * self.grad[:, 0] + ny * self.grad[:, 1]
        return np.sqrt(1.0 + along * along)


def downhill(grad: np.ndarray) -> np.ndarray:
    """``-∇Z / |∇Z|``: the horizontal direction straight down the bed (0 on a flat bed)."""
    return -grad / np.maximum(np.hypot(grad[:, 0], grad[:, 1]), 1e-300)[:, None]


@numba.njit(cache=True)
def _normal_acceleration(hess, ux, uy, g, out):
    """``out = max(g + u·H·u, 0)`` per node, ``u·H·u = u (Z_xx u + Z_xy v) + v (Z_xy u + Z_yy v)``.

    NaN propagates (as ``np.maximum``): a bad state is reported by the health check.
    """
    for i in range(out.shape[0]):
        x, y = ux[i], uy[i]
        uhu = x * (hess[i, 0] * x + hess[i, 1] * y) + y * (hess[i, 1] * x + hess[i, 2] * y)
        v = g + uhu
        out[i] = v if (v > 0.0 or v != v) else 0.0  # np.maximum(v, 0.0), -0.0 included


class SlopeGeometry:
    """Nodal bed geometry: gradient, Hessian and ``cos²θ`` of a Q1 bed, and the factor ``G``.

    Args:
        grad: (n, 2) nodal ``∇Z``.
        hess: (n, 3) nodal ``(Z_xx, Z_xy, Z_yy)``.
        gravity: ``g`` [m/s²].
        curvature: Add the centrifugal term to the friction's normal stress.
    """

    def __init__(self, grad: np.ndarray, hess: np.ndarray, gravity: float,
                 curvature: bool = False) -> None:
        self.grad = np.ascontiguousarray(grad, dtype=float)
        self.hess = np.ascontiguousarray(hess, dtype=float)
        self.g = float(gravity)
        self.curvature = bool(curvature)
        self.cos2 = 1.0 / (1.0 + self.grad[:, 0] ** 2 + self.grad[:, 1] ** 2)
        self.cos = np.sqrt(self.cos2)
        self._down: np.ndarray | None = None

    def take(self, nodes: np.ndarray) -> SlopeGeometry:
        """Return the geometry of a subset of the nodes (indices)."""
        return SlopeGeometry(self.grad[nodes], self.hess[nodes], self.g, self.curvature)

    def normal_acceleration(self, ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
        """``max(g + u·H·u, 0)``: vertical acceleration a flow following the bed needs [m/s²]."""
        out = np.empty(self.hess.shape[0])
        _normal_acceleration(self.hess, np.asarray(ux, dtype=float),
                             np.asarray(uy, dtype=float), self.g, out)
        return out

    def pressure_gravity(self, ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
        """``G = cos²θ max(g + u·H·u, 0)``, which replaces ``g`` in ``g h ∇(h + Z)``."""
        return np.multiply(self.normal_acceleration(ux, uy), self.cos2,
                           out=np.empty(self.cos2.shape))

    def frame(self, ux: np.ndarray | None = None, uy: np.ndarray | None = None) -> BedFrame:
        """Return the :class:`BedFrame` for friction (the velocity matters with ``curvature``)."""
        if self.curvature and ux is not None and uy is not None:
            normal = self.cos * self.normal_acceleration(ux, uy)
        else:
            normal = self.g * self.cos
        return BedFrame(self.grad, self.cos, normal, self)

    def downhill(self) -> np.ndarray:
        """:func:`downhill` of the nodes, formed once (the bed does not move)."""
        if self._down is None:
            self._down = downhill(self.grad)
        return self._down


def nodal_gradient(cell_sum, C: np.ndarray, cell_nodes: np.ndarray, lumped_mass: np.ndarray,
                   values: np.ndarray, n_owned_cells: int) -> np.ndarray:
    """Lumped L2 projection of ``∇f`` of a Q1 field onto Q1: ``Σ_K ∫_K φ_i ∇f / m_i``.

    Exact for a linear ``f`` (also on boundary nodes). ``cell_sum`` is
    :meth:`fem_runout.mesh.Discretization.cell_sum` (the same bits on any partition).

    Returns:
        (n_local, 2) nodal gradient, ghosts included.
    """
    n = n_owned_cells
    per = np.einsum("kijd,kj->kid", C[:n], values[cell_nodes[:n]])
    return cell_sum(np.ascontiguousarray(per)) / lumped_mass[:, None]


def lumped_gradient(disc, values: np.ndarray) -> np.ndarray:
    """:func:`nodal_gradient` of a nodal field on a discretization, (n_local, 2) (collective)."""
    return nodal_gradient(disc.cell_sum, disc.C, disc.cell_nodes, disc.lumped_mass,
                          np.ascontiguousarray(values, dtype=float), disc.n_owned_cells)


def lumped_hessian(disc, gradient: np.ndarray) -> np.ndarray:
    """``(H_xx, H_xy, H_yy)``: the lumped gradient of a nodal gradient, symmetrised (n_local, 3).

    Exact for a quadratic bed on a uniform grid away from the sides (collective).
    """
    gx, gy = lumped_gradient(disc, gradient[:, 0]), lumped_gradient(disc, gradient[:, 1])
    return np.stack([gx[:, 0], 0.5 * (gx[:, 1] + gy[:, 0]), gy[:, 1]], axis=1)


def slope_geometry(disc, z: np.ndarray, gravity: float, curvature: bool = False,
                   curvature_scale: float | None = None) -> SlopeGeometry:
    """Build the :class:`SlopeGeometry` of a Q1 bed on a discretization (collective).

    The gradient is the lumped projection of ``∇Z``; the Hessian that of the gradient's
    gradient, symmetrised (both exact for a plane, and the same bits on any partition). On a
    gmsh mesh the Hessian is then corrected to be exact for a quadratic bed, as it is on the
    grid (:mod:`fem_runout.physics.recovery`).

    Args:
        disc: A :class:`fem_runout.mesh.Discretization`.
        z: Nodal bed elevation (local, ghosts included).
        gravity: ``g`` [m/s²].
        curvature: Centrifugal term in the friction's normal stress.
        curvature_scale: Take ``H`` from the bed smoothed over this length [m]
            (:func:`fem_runout.physics.bed_filter.heat_smoothed`); None: from the bed itself.
    """
    grad = lumped_gradient(disc, z)
    base = grad if curvature_scale is None else lumped_gradient(
        disc, heat_smoothed(disc, z, curvature_scale))
    hess = (lumped_hessian(disc, base) if disc.structured
            else corrected_hessian(disc, base, lambda g: lumped_hessian(disc, g)))
    return SlopeGeometry(grad, hess, gravity, curvature)
