"""The background grid of DAMPM: fem_runout's Q1 space seen from the particles.

Particles are located by structured-grid index arithmetic (no bounding-box search): on the
``nx × ny`` rectangle a particle sits in column ``i`` and row ``j`` (structured index
``j nx + i``) at reference coordinates ``(ξ, η) ∈ [0, 1]²``; a displacement moves ``ξ`` and
carries whole cells into ``i`` (:meth:`ParticleGrid.displace`). Two dense tables, built once, turn
the structured index into the local DOLFINx cell (owned cells only) and into the rank that
owns the cell (for migration).

The Q1 basis at the particles is the basix P1 quadrilateral element of the state space at
``(ξ, η)``, in basix's dof order ``(0,0), (1,0), (0,1), (1,1)``; ``cell_nodes`` holds every
cell's local dofs in that order (the DOLFINx dofmap order of a cell need not be). It is
evaluated by :func:`bilinear_basis`, a numba kernel of the closed form that equals
``basix.tabulate`` to round-off (tested) and is ~5× faster for 5e5 particles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from fem_runout.mesh import Discretization

__all__ = ["Basis", "ParticleGrid", "bilinear_basis"]


@dataclass
class Basis:
    """Weights of the nodes a set of particles touches.

    Attributes:
        cells: (n,) cell of each particle (local DOLFINx cell for :meth:`ParticleGrid.basis`,
            structured index for the GIMP weights of :mod:`mpm.gimp`).
        nodes: (n, k) node indices: the cell's 4 local dofs in basix order
            (:meth:`ParticleGrid.basis`) or 9 structured nodes (:func:`mpm.gimp.gimp_weights`).
        N: (n, k) weights (``N_i(x_p)`` for point particles).
        dN: (n, k, 2) physical weight gradients.
    """

    cells: np.ndarray
    nodes: np.ndarray
    N: np.ndarray
    dN: np.ndarray


@numba.njit(cache=True)
def bilinear_basis(xi, eta, dx, dy):
    """Q1 values ``(n, 4)`` and physical gradients ``(n, 4, 2)`` at reference points.

    Dof order of basix's P1 quadrilateral: ``(0,0), (1,0), (0,1), (1,1)``.
    """
    n = xi.size
    N = np.empty((n, 4))
    dN = np.empty((n, 4, 2))
    for p in range(n):
        a, b = xi[p], eta[p]
        N[p, 0], N[p, 1] = (1.0 - a) * (1.0 - b), a * (1.0 - b)
        N[p, 2], N[p, 3] = (1.0 - a) * b, a * b
        dN[p, 0, 0], dN[p, 0, 1] = -(1.0 - b) / dx, -(1.0 - a) / dy
        dN[p, 1, 0], dN[p, 1, 1] = (1.0 - b) / dx, -a / dy
        dN[p, 2, 0], dN[p, 2, 1] = -b / dx, (1.0 - a) / dy
        dN[p, 3, 0], dN[p, 3, 1] = b / dx, a / dy
    return N, dN


#: Cost of a cell holding particles in the ranks' balance, in particles
#: (:func:`mpm.migrate.balanced_destinations`): the work of its nodes. Session 40 measured
#: the kernels alone on avaKot (DAMPM, 2 ranks): about 1.6 µs per touched node and step
#: against 0.41 µs per particle, a ratio of 4. With 4 the rank holding the spread flow did
#: -1 … +36 % (mean +18 %) more of the step's work between the collectives than the other
#: (timed phase by phase, five runs); with 10, -6 … +8 % (mean +0.7 %): the nodes also cost
#: outside the kernels (session 50, docs/performance.md).
CELL_COST = 10
#: No open side: :func:`_displace` keeps every point inside the rectangle.
_WALLS = np.zeros(4, dtype=np.bool_)


@numba.njit(cache=True)
def _displace(cell, xi, eta, dx, dy, hx, hy, nx, ny, open_side):
    """Points moved by ``(dx, dy)`` [m]: ``(cell, ξ, η, out)`` (:meth:`ParticleGrid.displace`).

    ``open_side``: left, right, bottom, top. A point past an open side is ``out`` (its cell is
    then meaningless); past a wall it is put on the wall. ``ξ + dx/Δx`` carries its whole
    part into the column (likewise ``η``), the sides are tested in the same pass (no
    temporaries).
    """
    n = cell.size
    new_cell = np.empty(n, dtype=np.int64)
    new_xi, new_eta = np.empty(n), np.empty(n)
    out = np.zeros(n, dtype=np.bool_)
    for p in range(n):
        s, t = xi[p] + dx[p] / hx, eta[p] + dy[p] / hy
        di, dj = np.floor(s), np.floor(t)
        i = cell[p] % nx + np.int64(di)
        j = cell[p] // nx + np.int64(dj)
        s, t = s - di, t - dj
        if i < 0 or i >= nx:
            if open_side[0 if i < 0 else 1]:
                out[p] = True
            else:
                i, s = (0, 0.0) if i < 0 else (nx - 1, 1.0)
        if j < 0 or j >= ny:
            if open_side[2 if j < 0 else 3]:
                out[p] = True
            else:
                j, t = (0, 0.0) if j < 0 else (ny - 1, 1.0)
        new_cell[p], new_xi[p], new_eta[p] = j * nx + i, s, t
    return new_cell, new_xi, new_eta, out


class ParticleGrid:
    """Locate points on the structured grid of a :class:`Discretization` and tabulate Q1 there.

    Args:
        disc: The shared discretization (mesh, Q1 space, cell–node arrays).
    """

    structured = True
    #: a cell's cost beyond its particles' in the ranks' balance
    unit_cost = CELL_COST

    def __init__(self, disc: Discretization) -> None:
        self.disc = disc
        self.comm = disc.comm
        self.nx, self.ny = disc.cells
        #: units of the ranks' strips (:meth:`rows`): the cells, in row-major order
        self.n_rows = self.nx * self.ny
        self.xmin, self.xmax, self.ymin, self.ymax = disc.extent
        self.dx, self.dy = disc.spacing
        self.min_size = min(self.dx, self.dy)
        self._open: np.ndarray | None = None  # which sides are open (displace), once known
        xc = disc.coords[disc.cell_nodes]  # (n_cells, 4, 2) dofmap order
        centre = xc.mean(axis=1)
        ij = self._column_row(centre[:, 0], centre[:, 1])
        self.cell_index = ij[1] * self.nx + ij[0]  # structured index of every local cell
        corner = (xc[:, :, 0] > centre[:, None, 0]).astype(int) + 2 * (
            xc[:, :, 1] > centre[:, None, 1]
        )
        order = np.argsort(corner, axis=1)
        self.cell_nodes = np.take_along_axis(disc.cell_nodes, order, axis=1)
        n_own = disc.n_owned_cells
        self.local_cell = np.full(self.nx * self.ny, -1, dtype=np.int64)
        self.local_cell[self.cell_index[:n_own]] = np.arange(n_own)
        owned = self.comm.allgather(self.cell_index[:n_own])
        self.owner = np.empty(self.nx * self.ny, dtype=np.int32)
        for rank, idx in enumerate(owned):
            self.owner[idx] = rank

    def _column_row(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i = np.clip(np.floor((x - self.xmin) / self.dx).astype(np.int64), 0, self.nx - 1)
        j = np.clip(np.floor((y - self.ymin) / self.dy).astype(np.int64), 0, self.ny - 1)
        return i, j

    def basis(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> Basis:
        """Q1 basis values and gradients at particles in the owned cells of this rank.

        Args:
            cell: (n,) structured cell indices (owned by this rank).
            xi: (n,) first reference coordinate in the cells.
            eta: (n,) second reference coordinate in the cells.

        Returns:
            The :class:`Basis` at the reference coordinates.

        Raises:
            ValueError: If a particle is not in a cell owned by this rank.
        """
        cells = self.local_cell[cell]
        if cells.size and cells.min() < 0:
            raise ValueError("a particle lies outside the cells owned by this rank")
        N, dN = bilinear_basis(np.ascontiguousarray(xi, dtype=float),
                               np.ascontiguousarray(eta, dtype=float), self.dx, self.dy)
        return Basis(cells, self.cell_nodes[cells], N, dN)

    def owned_cells(self) -> np.ndarray:
        """Structured indices of the cells this rank owns (local cell order)."""
        return self.cell_index[: self.disc.n_owned_cells]

    def cell_origin(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower-left corner of structured cells."""
        return self.xmin + (index % self.nx) * self.dx, self.ymin + (index // self.nx) * self.dy

    # -- what the solver asks of any background grid (also :class:`mpm.mesh_grid.MeshParticleGrid`)
    @property
    def transfers(self):
        """The factored GIMP kernels (:data:`mpm.transfers.GIMP`)."""
        from mpm.transfers import GIMP

        return GIMP

    def particle_basis(self, p):
        """GIMP weights of particles ``p`` (:func:`mpm.gimp.gimp_basis`)."""
        from mpm.gimp import gimp_basis

        return gimp_basis(p.cell, p.xi, p.eta, p.lx, p.ly, self.nx, self.ny, self.dx, self.dy)

    def projector(self):
        """Return the particle → Q1 projection (:class:`mpm.projection.GridProjector`)."""
        from mpm.projection import GridProjector

        return GridProjector(self.disc.cells, self.disc.spacing)

    def rows(self, cell: np.ndarray) -> np.ndarray:
        """Strip unit of each cell (:func:`mpm.migrate.balanced_destinations`): the cell itself.

        The strips are runs of cells in row-major order, whole grid rows but at their ends: a
        strip of whole rows missed the even split by up to one row's particles, thousands in
        a deposit (avaKot's last 100 steps: 7-15 % more particles on one of two ranks).
        """
        return cell

    def balance_weights(self, p) -> None:
        """Per-particle cost for :func:`mpm.migrate.balanced_destinations`: None (counts)."""
        return None

    def positions(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Physical coordinates of points given in cells."""
        x0, y0 = self.cell_origin(cell)
        return x0 + xi * self.dx, y0 + eta * self.dy

    def areas(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray,
              weights: np.ndarray) -> np.ndarray:
        """``w Δx Δy``: the area a quadrature weight stands for."""
        return weights * self.dx * self.dy

    def split_limits(self, cell: np.ndarray, per_direction: int
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Largest half-widths of a particle domain, ``min(Δ/n, Δ/2)`` per axis."""
        shape = np.shape(cell)
        return (np.full(shape, min(self.dx / per_direction, 0.5 * self.dx)),
                np.full(shape, min(self.dy / per_direction, 0.5 * self.dy)))

    def aspect(self, cell: np.ndarray) -> np.ndarray:
        """``Δx/Δy`` of the cells (the unit of a particle domain's aspect ratio)."""
        return np.full(np.shape(cell), self.dx / self.dy)

    def displace(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray, dx: np.ndarray,
                 dy: np.ndarray) -> tuple[np.ndarray, ...]:
        """Move points by ``(dx, dy)`` [m]: ``(cell, ξ, η, out, swap)``.

        Points past an open side are marked ``out``; a wall side stops them at the wall.
        ``swap`` is None: every cell has the same axes.
        """
        if self._open is None:
            kinds = {s.name: s.kind for s in self.disc.sides}
            self._open = np.array([kinds[n] == "open" for n in ("left", "right", "bottom",
                                                                 "top")])
        cell, xi, eta, out = _displace(cell, xi, eta, dx, dy, self.dx, self.dy, self.nx,
                                       self.ny, self._open)
        return cell, xi, eta, out, None

    def axis_rates(self, p, grad: np.ndarray) -> np.ndarray:
        """Stretch rates along the axes: the velocity gradient itself (its diagonal is read)."""
        return grad

    def shift_along(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray, axis: int,
                    dist: np.ndarray) -> tuple[np.ndarray, ...]:
        """Move points by ``dist`` along x (axis 0) or y, kept inside: ``(cell, ξ, η, None)``."""
        zero = np.zeros_like(dist)
        dx, dy = (dist, zero) if axis == 0 else (zero, dist)
        cell, xi, eta, _ = _displace(cell, xi, eta, dx, dy, self.dx, self.dy, self.nx, self.ny,
                                     _WALLS)
        return cell, xi, eta, None
