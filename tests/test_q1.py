"""The Q1 basis in closed form: basix's values, and the same bits whatever BLAS kernels run.

basix tabulates through BLAS; OpenBLAS picks its kernels by CPU (``OPENBLAS_CORETYPE``
forces one), and the tabulated values differed by an ulp between kernels, which moved the
cell integrals of a DEM in national coordinates by 1e-11 and DAMPM's avaKot stop by six steps.
"""

import hashlib
import os
import subprocess
import sys

import basix
import numpy as np

from fem_runout.q1 import inverses, jacobians, q1_basis

SCRIPT = """
import hashlib, numpy as np
from fem_runout.mesh import cell_integrals, element_masses
from fem_runout.tg2.edges import edge_dzdn
rng = np.random.default_rng(7)
n = 400
base = np.array([[0, 0], [10, 0], [0, 10], [10, 10]], dtype=float)
xc = 4.1e5 + base[None] + rng.uniform(-2.5, 2.5, (n, 4, 2))
xc[:, :, 1] += 2.9e5
C, phi_int, area = cell_integrals(xc)
coords = xc.reshape(-1, 2)
cells = np.arange(4 * n).reshape(n, 4)
mass = element_masses(cells, coords)
normal = rng.standard_normal((n, 4, 2))
dz = edge_dzdn(1000 + rng.random(4 * n), coords, cells, normal)
digest = hashlib.sha256()
for a in (C, phi_int, area, mass, dz):
    digest.update(np.ascontiguousarray(a).tobytes())
print(digest.hexdigest())
"""


def test_closed_form_is_basix_q1_to_an_ulp():
    pts, _ = basix.make_quadrature(basix.CellType.quadrilateral, 4)
    tab = basix.create_element(basix.ElementFamily.P, basix.CellType.quadrilateral,
                               1).tabulate(1, pts)
    phi, dphi = q1_basis(pts)
    assert np.abs(phi - tab[0, :, :, 0]).max() <= 2.3e-16
    assert np.abs(dphi[..., 0] - tab[1, :, :, 0]).max() <= 4.5e-16
    assert np.abs(dphi[..., 1] - tab[2, :, :, 0]).max() <= 4.5e-16
    assert np.all(dphi.sum(axis=1) == 0.0)  # exactly: Σ ∇φ = 0


def test_jacobians_do_not_see_the_coordinates_offset():
    """A parallelogram's tangents, relative to its first corner: the same bits at any offset
    (the corners are exact there), and the exact tangents to round-off."""
    e1, e2 = np.array([3.0, 1.0]), np.array([-1.0, 2.0])
    _, dphi = q1_basis(np.array([[0.2, 0.7], [0.5, 0.5]]))
    found = []
    for offset in (0.0, 4.0e5, 3.0e6):
        x0 = np.array([offset, offset])
        found.append(jacobians(np.array([[x0, x0 + e1, x0 + e2, x0 + e1 + e2]]), dphi))
    assert all(np.array_equal(found[0], f) for f in found[1:])
    assert np.abs(found[0] - np.array([[3.0, -1.0], [1.0, 2.0]])).max() <= 8 * np.finfo(float).eps


def test_cell_integrals_have_the_same_bits_with_any_blas_kernels():
    """The same digest under OpenBLAS's SSE3 (runs on any x86-64) and default kernels."""
    digests = set()
    for core in ("Prescott", None):
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
        if core is not None:
            env["OPENBLAS_CORETYPE"] = core
        out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                             env=env, check=True, timeout=120)
        digests.add(out.stdout.split()[-1])
    assert len(digests) == 1, digests
    assert len(next(iter(digests))) == len(hashlib.sha256().hexdigest())


def test_inverses_by_the_adjugate():
    """``J⁻¹ J = I`` to round-off and ``det J`` for a batch of bilinear maps' Jacobians."""
    rng = np.random.default_rng(3)
    J = rng.uniform(0.5, 2.0, (50, 3, 2, 2))
    J[..., 0, 1] *= 0.3
    J[..., 1, 0] *= -0.3
    inv, det = inverses(J)
    assert np.abs(np.einsum("...ab,...bc->...ac", inv, J) - np.eye(2)).max() <= 1e-14
    assert np.array_equal(det, J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0])


def test_jacobians_and_gradients_have_einsums_bits():
    """The explicit sums give np.einsum's bits, the signs of zeros included."""
    from fem_runout.q1 import inverses, jacobians, physical_gradients, q1_basis

    rng = np.random.default_rng(7)
    square = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    xc = np.concatenate([  # axis-aligned squares (exact zeros) and skewed cells, far out
        5e5 + square[None] + 10.0 * rng.integers(0, 100, (50, 1, 2)),
        3e5 + square[None] + rng.normal(0.0, 2.0, (500, 4, 2)) + 1e3 * rng.random((500, 1, 2))])
    for pts in (rng.random((9, 2)), np.array([[0.5, 0.5]])):
        _, dphi = q1_basis(pts)
        rel = xc - xc[:, :1, :]
        jac = jacobians(xc, dphi)
        want = np.einsum("cka,qkb->cqab", rel, dphi)
        assert np.array_equal(jac, want) and np.array_equal(np.signbit(jac), np.signbit(want))
        inv = inverses(jac)[0]
        grad = physical_gradients(dphi, inv)
        want = np.einsum("qkb,cqba->cqka", dphi, inv)
        assert np.array_equal(grad, want) and np.array_equal(np.signbit(grad),
                                                             np.signbit(want))
    assert np.count_nonzero(jac == 0.0) > 0  # the squares' off-diagonal zeros were compared
