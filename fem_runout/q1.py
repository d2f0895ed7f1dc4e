"""The Q1 reference basis in closed form, with the same bits on every CPU.

basix tabulates its elements through BLAS, and OpenBLAS picks its kernels by CPU: the Q1
values and derivatives at the Gauss points came out one ulp apart between a Cascade Lake Xeon
(OpenBLAS's SkylakeX kernels) and the Haswell or Zen kernels. Multiplied by node coordinates
of 10⁵–10⁶ m (a DEM in a national grid), that ulp moved the cell integrals ``C`` and the
lumped mass by 1e-11 relative, and DAMPM's avaKot run stopped at rest after 941 steps on one
CPU and 935 on others (found with ``OPENBLAS_CORETYPE``; docs/method.md, "Parallel"). The
formulas below are exact products and differences of the points' coordinates, so every CPU
gives the same bits; :func:`jacobians` takes the cells' corners relative to their first
corner, so the map's tangents do not lose digits to the coordinates' size either.
"""

from __future__ import annotations

import numpy as np

__all__ = ["inverses", "jacobians", "physical_gradients", "q1_basis"]


def q1_basis(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Q1 values (nq, 4) and reference derivatives (nq, 4, 2) at reference points (nq, 2).

    basix's corner order ``(0,0), (1,0), (0,1), (1,1)``: ``φ = (1-ξ)(1-η), ξ(1-η), (1-ξ)η,
    ξη``. The derivatives of each point sum to zero exactly.
    """
    p = np.asarray(points, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    mx, my = 1.0 - x, 1.0 - y
    phi = np.stack([mx * my, x * my, mx * y, x * y], axis=1)
    dx = np.stack([-my, my, -y, y], axis=1)
    dy = np.stack([-mx, -x, mx, x], axis=1)
    return phi, np.stack([dx, dy], axis=-1)


def jacobians(xc: np.ndarray, dphi: np.ndarray) -> np.ndarray:
    """``∂x_a/∂ξ_b`` of bilinear cells (n, 4, 2) at points with derivatives ``dphi`` (q, 4, 2).

    Returns (n, q, 2, 2), from the corners relative to each cell's first corner (the same
    map, since the derivatives sum to zero, without the coordinates' magnitude).
    """
    rel = xc - xc[:, :1, :]
    out = np.zeros((rel.shape[0], dphi.shape[0], 2, 2))
    for k in range(4):  # einsum("cka,qkb->cqab")'s sums, in its order, without its slow path
        out += rel[:, None, k, :, None] * dphi[None, :, k, None, :]
    return out


def physical_gradients(dphi: np.ndarray, inv: np.ndarray) -> np.ndarray:
    """Physical gradients ``∂φ_k/∂x_a = Σ_b ∂φ_k/∂ξ_b ∂ξ_b/∂x_a``, (n, q, 4, 2).

    ``dphi`` (q, 4, 2) reference derivatives, ``inv`` (n, q, 2, 2) inverse Jacobians. The
    bits of ``np.einsum("qkb,cqba->cqka", dphi, inv)`` (the sum from zero, ``b = 0`` first;
    tested), four times faster: einsum broadcasting ``dphi`` over the cells took 0.5–0.7 s
    on avaKot's 56 502 cells, on every run.
    """
    out = np.zeros((inv.shape[0], dphi.shape[0], dphi.shape[1], 2))
    for b in range(2):
        out += dphi[None, :, :, b, None] * inv[:, :, None, b, :]
    return out


def inverses(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverses and determinants of 2×2 matrices ``(..., 2, 2)`` by the adjugate.

    No LAPACK (``np.linalg.inv`` goes through the CPU's BLAS kernels): the same bits anywhere.
    """
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    inv = np.empty_like(J)
    inv[..., 0, 0], inv[..., 1, 1] = J[..., 1, 1] / det, J[..., 0, 0] / det
    inv[..., 0, 1], inv[..., 1, 0] = -J[..., 0, 1] / det, -J[..., 1, 0] / det
    return inv, det
