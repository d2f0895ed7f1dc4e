"""The bed's Hessian on unstructured meshes is exact for quadratic beds (issue 17)."""

import numpy as np
from mpi4py import MPI

from fem_runout.physics.recovery import monomial_gradients
from fem_runout.physics.slope import lumped_gradient, lumped_hessian, slope_geometry
from tests.quad_helpers import distorted_rectangle

EXTENT = (0.0, 100.0, 0.0, 80.0)
CELLS = (20, 16)  # 5 m cells
SIDES = {s: "open" for s in ("left", "right", "bottom", "top")}
HESS = np.array([0.004, 0.003, -0.002])


def _bed(disc) -> np.ndarray:
    """A tilted, curved quadratic bed: ``Z_xx = 0.004, Z_xy = 0.003, Z_yy = -0.002``."""
    x, y = disc.coords[:, 0] - 50.0, disc.coords[:, 1] - 40.0
    return 0.5 * HESS[0] * x * x + HESS[1] * x * y + 0.5 * HESS[2] * y * y - 0.4 * x + 0.1 * y


def _plain_hessian(disc, z: np.ndarray) -> np.ndarray:
    """The lumped projection applied twice, uncorrected (the grid's Hessian)."""
    return lumped_hessian(disc, lumped_gradient(disc, z))


def test_curvature_of_a_quadratic_bed_is_exact_on_a_jittered_mesh():
    disc = distorted_rectangle(MPI.COMM_SELF, EXTENT, CELLS, SIDES, amp=0.25, seed=3)
    z = _bed(disc)
    geometry = slope_geometry(disc, z, 9.81, True)
    # every node, sides and corners included; round-off: z ~ 20 m carries ~1e-14 m,
    # differenced twice over 5 m cells: ~1e-13 m⁻¹ per pass
    assert np.abs(geometry.hess - HESS).max() <= 1e-10
    # what the correction removes: the plain projection errs by several per cent
    plain = np.abs(_plain_hessian(disc, z) - HESS).max()
    assert plain >= 0.05 * np.abs(HESS).max()
    # a plane's Hessian stays round-off (the passes stop at once)
    plane = slope_geometry(disc, 3.0 - 0.4 * disc.coords[:, 0] + 0.1 * disc.coords[:, 1], 9.81)
    assert np.abs(plane.hess).max() <= 1e-12


def test_uniform_unstructured_mesh_keeps_the_grid_hessian():
    """On a uniform mesh the monomials' lumped gradients vanish: the grid's Hessian, unchanged."""
    disc = distorted_rectangle(MPI.COMM_SELF, EXTENT, CELLS, SIDES, amp=0.0, seed=3)
    z = _bed(disc) + 0.3 * np.sin(disc.coords[:, 0] / 7.0) * np.cos(disc.coords[:, 1] / 11.0)
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    inner = (x > 1.0) & (x < 99.0) & (y > 1.0) & (y < 79.0)  # (one-sided patches on the sides)
    assert np.abs(monomial_gradients(disc)[inner]).max() <= 1e-12
    deep = (x > 11.0) & (x < 89.0) & (y > 11.0) & (y < 69.0)  # no side node in the stencil
    np.testing.assert_allclose(slope_geometry(disc, z, 9.81, True).hess[deep],
                               _plain_hessian(disc, z)[deep], rtol=0, atol=1e-12)
