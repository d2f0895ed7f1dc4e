"""Particle → Q1 projection of the depth and momenta for outputs and diagnostics.

The particles carry the state; the grid fields ``h, hu, hv`` that every output reads are
projections of the particle volume spread over the particle domains (GIMP weights ``S_ip`` of
:mod:`mpm.gimp`; ``S_ip = N_i(x_p)`` for a domain inside one cell):

* low order (lumped): ``h^L_i = b_i / M_i`` with ``b_i = Σ_p V_p S_ip`` and the lumped Q1
  mass ``M_i = ∫ φ_i`` — non-negative, but smeared by one cell;
* high order (consistent L2): ``M_C h^H = b`` — exact for a nodal field sampled by particles
  at Gauss points (lake at rest to round-off), but it can undershoot at fronts.

They are blended per cell as in flux-corrected transport: ``h = h^L + M_L^{-1} Σ_K α_K f_K``
with the element antidiffusion ``f_K = (M_L^K - M_C^K) h^H`` (``Σ_i f_{K,i} = 0``, so any
``α_K`` conserves ``Σ_i M_i h_i = Σ_p V_p`` exactly) and ``α_K = 1`` except in the cells
touching a node that would get a negative depth, where ``α_K = 0`` (repeated until no node is
negative). Further columns (if any) use the same ``α_K``. The solver projects ``h`` this way
and writes ``hu = h v̄`` with the mass-averaged particle velocity ``v̄_i = Σ m_p v_p S_ip / M_i``
(bounded by the particle velocities, so the output speed never exceeds the particles').

On the structured grid the consistent mass matrix is a tensor product, ``M_C = M_y ⊗ M_x``
with the 1D matrices ``Δ/6 tridiag(1, 4, 1)`` (2 at the ends), so ``M_C^{-1} b`` is two sweeps
of tridiagonal solves (rows, then columns): exact, O(N), no iteration. The projector works on
the global structured node array (index ``j (nx + 1) + i``), which the solver sums over the
ranks once per step; every rank then projects the whole (cheap) grid, with no communication.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["GridProjector", "tridiagonal_mass_solve"]

#: Element mass matrix of a rectangle over |K| (basix dof order (0,0), (1,0), (0,1), (1,1)).
_MASS_REF = np.array([[4, 2, 2, 1], [2, 4, 1, 2], [2, 1, 4, 2], [1, 2, 2, 4]]) / 36.0


@numba.njit(cache=True)
def tridiagonal_mass_solve(rhs):
    """Solve ``M x = rhs`` along the last axis for ``M = tridiag(1, 4, 1)/6`` (2/6 at the ends).

    Args:
        rhs: (m, n) right-hand sides, one per row (n >= 2).

    Returns:
        (m, n) solutions (Thomas algorithm; the matrix is strictly diagonally dominant).
    """
    m, n = rhs.shape
    out = np.empty_like(rhs)
    c = np.empty(n)
    for r in range(m):
        diag = 2.0 / 6.0
        c[0] = (1.0 / 6.0) / diag
        out[r, 0] = rhs[r, 0] / diag
        for k in range(1, n):
            d = (2.0 if k == n - 1 else 4.0) / 6.0
            denom = d - (1.0 / 6.0) * c[k - 1]
            c[k] = (1.0 / 6.0) / denom
            out[r, k] = (rhs[r, k] - (1.0 / 6.0) * out[r, k - 1]) / denom
        for k in range(n - 2, -1, -1):
            out[r, k] -= c[k] * out[r, k + 1]
    return out


@numba.njit(cache=True)
def _cells_hit(cells, bad, alpha):
    """Cells with ``α_K > 0`` that touch a bad node."""
    hit = np.zeros(cells.shape[0], dtype=np.bool_)
    for c in range(cells.shape[0]):
        if alpha[c] > 0.0:
            for i in range(4):
                if bad[cells[c, i]]:
                    hit[c] = True
                    break
    return hit


@numba.njit(cache=True)
def _antidiffusion(cells, matrix, high, alpha, n_nodes):
    """``Σ_K α_K (M_L^K - M_C^K) high`` scattered to the nodes; (n_nodes, k)."""
    out = np.zeros((n_nodes, high.shape[1]))
    for c in range(cells.shape[0]):
        if alpha[c] == 0.0:
            continue
        for i in range(4):
            for j in range(4):
                w = alpha[c] * matrix[i, j]
                for k in range(high.shape[1]):
                    out[cells[c, i], k] += w * high[cells[c, j], k]
    return out


class GridProjector:
    """Project particle sums onto Q1 (lumped / consistent, FCT-blended for h >= 0).

    Works on global structured node arrays (index ``j (nx + 1) + i``).

    Args:
        cells: ``(nx, ny)`` cells of the rectangle.
        spacing: ``(Δx, Δy)`` [m].
    """

    def __init__(self, cells: tuple[int, int], spacing: tuple[float, float]) -> None:
        nx, ny = cells
        self.shape = (ny + 1, nx + 1)
        self.area = spacing[0] * spacing[1]
        self.matrix = self.area * (np.eye(4) / 4.0 - _MASS_REF)
        i, j = np.meshgrid(np.arange(nx), np.arange(ny))
        base = (j * (nx + 1) + i).ravel()
        self.cells = np.stack([base, base + 1, base + nx + 1, base + nx + 2], axis=1)
        lumped = np.zeros((ny + 1) * (nx + 1))
        np.add.at(lumped, self.cells.ravel(), 0.25 * self.area)
        self.lumped_mass = lumped
        self.iterations = 0

    def consistent(self, b: np.ndarray) -> np.ndarray:
        """``M_C^{-1} b`` for (n_nodes, k) nodal sums; (n_nodes, k)."""
        k = b.shape[1]
        ny1, nx1 = self.shape
        grid = b.reshape(ny1, nx1, k).transpose(2, 0, 1)  # (k, ny+1, nx+1)
        rows = tridiagonal_mass_solve(np.ascontiguousarray(grid.reshape(k * ny1, nx1)))
        rows = rows.reshape(k, ny1, nx1).transpose(0, 2, 1).reshape(k * nx1, ny1)
        sol = tridiagonal_mass_solve(np.ascontiguousarray(rows)).reshape(k, nx1, ny1)
        return sol.transpose(2, 1, 0).reshape(ny1 * nx1, k) / self.area

    def project(self, b: np.ndarray) -> np.ndarray:
        """Blend of the lumped and consistent projections of ``b`` (see the module docstring).

        Args:
            b: (n_nodes, k) global nodal sums, first ``Σ_p V_p S_ip`` (then e.g.
                ``Σ_p V_p u_p S_ip``).

        Returns:
            (n_nodes, k) nodal fields, the first (``h``) >= 0.
        """
        mass = self.lumped_mass[:, None]
        low = b / mass
        high = self.consistent(b)
        alpha = np.ones(self.cells.shape[0])
        tol = 1e-13 * float(np.abs(low[:, 0]).max(initial=0.0))
        self.iterations = 0
        while True:
            self.iterations += 1
            anti = _antidiffusion(self.cells, self.matrix, high, alpha, b.shape[0])
            out = low + anti / mass
            hit = _cells_hit(self.cells, out[:, 0] < -tol, alpha)
            if not hit.any():
                break
            alpha[hit] = 0.0
        out[:, 0] = np.maximum(out[:, 0], 0.0)
        return out
