"""Particle-domain (GIMP) weights of the Q1 basis on the structured grid.

Each particle is the centre of a rectangle ``[x_p ± l_x] × [y_p ± l_y]`` (its column's
footprint, half-widths stretched with the flow, :mod:`mpm.split`). Its weights are the Q1
basis averaged over that rectangle, the generalized interpolation of Bardenhagen & Kober (2004)
with convected domains (cpGIMP, Sadeghirad et al. 2011, axis-aligned):

    S_ip = (1/|Ω_p|) ∫_{Ω_p} N_i dx,        ∇S_ip = (1/|Ω_p|) ∫_{Ω_p} ∇N_i dx.

On the tensor grid both are products of 1D averages of the hat function, in closed form from
its antiderivative. A domain inside one cell gives the Q1 point values ``N_i(x_p)`` exactly
(bilinear functions average to their centre value), so particles seeded inside their cells
start as the point particles of seed eq. 33, and a lake at rest stays exact. A domain crossing
a grid line spreads the particle over the nodes it covers: a stretched column reaches the
nodes it physically overlaps, which the point particle of the seed cannot (its front lags).

Domains are clipped to the rectangle and averaged over the clipped part, so ``Σ_i S_ip = 1``
(the particle's mass is on the grid exactly) and ``Σ_i ∇S_ip = 0``. Half-widths are at most
half a cell (splitting keeps them there), so a domain covers at most 2 cells per direction:
3 × 3 nodes, addressed by their structured index ``j (nx + 1) + i`` on the global node array.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["GimpBasis", "gimp_basis", "gimp_weights", "structured_nodes"]


@numba.njit(cache=True, inline="always")
def _hat_integral(t):
    """Antiderivative of the hat ``max(0, 1 - |t|)`` (0 below -1, 1 above 1)."""
    if t <= -1.0:
        return 0.0
    if t <= 0.0:
        return 0.5 * (t + 1.0) ** 2
    if t <= 1.0:
        return 1.0 - 0.5 * (1.0 - t) ** 2
    return 1.0


@numba.njit(cache=True, inline="always")
def _hat(t):
    return max(0.0, 1.0 - abs(t))


@numba.njit(cache=True, inline="always")
def _axis(cell, ref, half, n, k0, w, dw, p, inv):
    """Write the 1D weights of nodes ``k0, k0+1, k0+2`` into row ``p``.

    Positions are in cell units; ``dw`` is the derivative times ``inv`` (1 / cell width).
    """
    s = cell + ref
    lo, hi = max(s - half, 0.0), min(s + half, float(n))
    inside = lo >= cell - 1e-9 and hi <= cell + 1.0 + 1e-9  # (a protrusion of 1e-9 cells
    # changes the weights by ~1e-18)
    if lo > s - half or hi < s + half:  # clipped at the edge: the clipped domain's centre
        ref = 0.5 * (lo + hi) - cell
    for a in range(3):
        k = k0 + a
        if inside or hi - lo < 1e-12:  # the point values of the seed (exactly)
            if k == cell:
                w[p, a], dw[p, a] = 1.0 - ref, -inv
            elif k == cell + 1:
                w[p, a], dw[p, a] = ref, inv
            else:
                w[p, a], dw[p, a] = 0.0, 0.0
        else:
            w[p, a] = (_hat_integral(hi - k) - _hat_integral(lo - k)) / (hi - lo)
            dw[p, a] = (_hat(hi - k) - _hat(lo - k)) / (hi - lo) * inv


@dataclass
class GimpBasis:
    """GIMP weights of the 3 × 3 nodes around every particle, as their two 1D factors.

    Node ``(a, b)`` of particle ``p`` (``a, b`` in 0..2) is the structured node
    ``min(j0 + b, ny) (nx + 1) + min(i0 + a, nx)`` with weight ``S = wx[p, a] wy[p, b]`` and
    gradient ``(dwx[p, a] wy[p, b], wx[p, a] dwy[p, b])`` (derivatives per metre). The
    kernels of :mod:`mpm.kernels` form these products as they go: 112 bytes per particle to
    read instead of the 288 of the expanded arrays (:meth:`expand`).

    Attributes:
        i0, j0: (n,) first node column and row.
        wx, dwx: (n, 3) weights and derivatives [1/m] along x.
        wy, dwy: (n, 3) the same along y.
        grid: ``(nx, ny, Δx, Δy)``.
    """

    i0: np.ndarray
    j0: np.ndarray
    wx: np.ndarray
    dwx: np.ndarray
    wy: np.ndarray
    dwy: np.ndarray
    grid: tuple[int, int, float, float]

    @property
    def arrays(self) -> tuple:
        """The arguments the kernels take first: the factors, then ``nx, ny, Δx, Δy``."""
        return (self.i0, self.j0, self.wx, self.dwx, self.wy, self.dwy, *self.grid)

    def expand(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the expanded arrays ``(nodes, S, dS)``.

        They are (n, 9) node indices (non-decreasing along each row; valid even where the
        weight is zero), (n, 9) weights and (n, 9, 2) physical weight gradients.
        """
        return _expand(*self.arrays)


@numba.njit(cache=True)
def _expand(i0, j0, wx, dwx, wy, dwy, nx, ny, dx, dy):
    n = i0.size
    nodes = np.empty((n, 9), dtype=np.int64)
    S = np.empty((n, 9))
    dS = np.empty((n, 9, 2))
    for p in range(n):
        for b in range(3):
            for a in range(3):
                q = 3 * b + a
                nodes[p, q] = min(j0[p] + b, ny) * (nx + 1) + min(i0[p] + a, nx)
                S[p, q] = wx[p, a] * wy[p, b]
                dS[p, q, 0] = dwx[p, a] * wy[p, b]
                dS[p, q, 1] = wx[p, a] * dwy[p, b]
    return nodes, S, dS


@numba.njit(cache=True)
def _gimp_axes(cell, xi, eta, lx, ly, nx, ny, dx, dy):
    n = cell.size
    i0s, j0s = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    wx, dwx, wy, dwy = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for p in range(n):
        i, j = cell[p] % nx, cell[p] // nx
        ax, ay = lx[p] / dx, ly[p] / dy
        i0 = min(max(int(np.floor(i + xi[p] - ax + 1e-9)), 0), nx - 1)
        j0 = min(max(int(np.floor(j + eta[p] - ay + 1e-9)), 0), ny - 1)
        _axis(i, xi[p], ax, nx, i0, wx, dwx, p, 1.0 / dx)
        _axis(j, eta[p], ay, ny, j0, wy, dwy, p, 1.0 / dy)
        i0s[p], j0s[p] = i0, j0
    return i0s, j0s, wx, dwx, wy, dwy


def gimp_basis(cell: np.ndarray, xi: np.ndarray, eta: np.ndarray, lx: np.ndarray,
               ly: np.ndarray, nx: int, ny: int, dx: float, dy: float) -> GimpBasis:
    """GIMP weights of the 3 × 3 nodes around every particle, in factored form.

    Args:
        cell: (n,) structured cell index ``j nx + i``.
        xi: (n,) reference x in the cell.
        eta: (n,) reference y in the cell.
        lx: (n,) domain half-width in x [m] (<= Δx/2).
        ly: (n,) domain half-width in y [m] (<= Δy/2).
        nx: Cells along x.
        ny: Cells along y.
        dx: Cell width [m].
        dy: Cell height [m].
    """
    return GimpBasis(*_gimp_axes(cell, xi, eta, lx, ly, nx, ny, dx, dy),
                     (int(nx), int(ny), float(dx), float(dy)))


def gimp_weights(cell: np.ndarray, xi: np.ndarray, eta: np.ndarray, lx: np.ndarray,
                 ly: np.ndarray, nx: int, ny: int, dx: float, dy: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the expanded GIMP weights ``(nodes, S, dS)`` (see :meth:`GimpBasis.expand`)."""
    return gimp_basis(cell, xi, eta, lx, ly, nx, ny, dx, dy).expand()


def structured_nodes(coords: np.ndarray, extent: tuple[float, float, float, float],
                     spacing: tuple[float, float], cells: tuple[int, int]) -> np.ndarray:
    """Structured index ``j (nx + 1) + i`` of nodes given by their coordinates."""
    xmin, _, ymin, _ = extent
    col = np.rint((coords[:, 0] - xmin) / spacing[0]).astype(np.int64)
    row = np.rint((coords[:, 1] - ymin) / spacing[1]).astype(np.int64)
    return row * (cells[0] + 1) + col
