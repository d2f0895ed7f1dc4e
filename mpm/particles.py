"""Material points of DAMPM (seed §3.2.1): flat numpy arrays, seeding and (un)packing.

Positions are stored cell-locally: the structured cell index ``cell = j nx + i`` and the
reference coordinates ``(ξ, η) ∈ [0, 1]²`` in it (``x = xmin + (i + ξ) Δx``). The Q1 basis
then has full precision wherever the domain sits (absolute coordinates far from the origin
would lose digits in ``ξ``), and particles seeded at the Gauss points keep exactly the Gauss
reference coordinates, which makes the lake at rest exact to round-off on the grid.

Each particle is a column of material with a fixed mass ``m_p = ρ h_p A_p`` (seed eq. 29),
volume ``V_p = m_p/ρ``, depth ``h_p`` (so its area is ``A_p = V_p/h_p``), velocity
``v_p`` and depth-integrated stress ``σ_p`` (``xx, yy, xy``). A global ``id`` identifies a
particle independently of the rank count (migration is checked against it).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import basix
import numpy as np

from mpm.grid import ParticleGrid
from mpm.kernels import interpolate

__all__ = ["FLOAT_FIELDS", "Particles", "seed_particles"]

#: Per-particle float arrays (the ``id`` is int64).
FLOAT_FIELDS = ("xi", "eta", "volume", "h", "u", "v", "sxx", "syy", "sxy")


@dataclass
class Particles:
    """Particle state as flat arrays of equal length.

    Attributes:
        xi, eta: Reference coordinates in the cell, in [0, 1].
        volume: ``V_p = m_p/ρ`` [m³] (fixed).
        h: Depth ``h_p`` [m] (seed eq. 42).
        u, v: Velocity [m/s].
        sxx, syy, sxy: Depth-averaged deviatoric stress ``σ_p`` [Pa] (seed eq. 41).
        cell: Structured cell index ``j nx + i``.
        id: Global particle id.
    """

    xi: np.ndarray
    eta: np.ndarray
    volume: np.ndarray
    h: np.ndarray
    u: np.ndarray
    v: np.ndarray
    sxx: np.ndarray
    syy: np.ndarray
    sxy: np.ndarray
    cell: np.ndarray
    id: np.ndarray

    def __len__(self) -> int:
        return int(self.xi.size)

    def positions(self, grid: ParticleGrid) -> tuple[np.ndarray, np.ndarray]:
        """Physical coordinates ``(x, y)`` [m]."""
        x0, y0 = grid.cell_origin(self.cell)
        return x0 + self.xi * grid.dx, y0 + self.eta * grid.dy

    @property
    def area(self) -> np.ndarray:
        """Column area ``A_p = V_p / h_p`` [m²]."""
        return self.volume / self.h

    def copy(self) -> Particles:
        """Deep copy."""
        return Particles(**{f.name: getattr(self, f.name).copy() for f in fields(self)})

    def select(self, mask: np.ndarray) -> Particles:
        """Return the particles where ``mask`` is true (or at the given indices)."""
        return Particles(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})

    def pack(self) -> np.ndarray:
        """(n, 11) float64 rows for MPI exchange (cell and id stored exactly as float64 views)."""
        out = np.empty((len(self), len(FLOAT_FIELDS) + 2))
        for k, name in enumerate(FLOAT_FIELDS):
            out[:, k] = getattr(self, name)
        out[:, -2] = self.cell.view(np.float64)
        out[:, -1] = self.id.view(np.float64)
        return out

    @classmethod
    def unpack(cls, rows: np.ndarray) -> Particles:
        """Inverse of :meth:`pack`."""
        rows = np.ascontiguousarray(rows).reshape(-1, len(FLOAT_FIELDS) + 2)
        data = {name: rows[:, k].copy() for k, name in enumerate(FLOAT_FIELDS)}
        cell = np.ascontiguousarray(rows[:, -2]).view(np.int64).copy()
        return cls(**data, cell=cell, id=np.ascontiguousarray(rows[:, -1]).view(np.int64).copy())

    @classmethod
    def concatenate(cls, parts: list[Particles]) -> Particles:
        """Join several particle sets."""
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                      for f in fields(cls)})


def seed_particles(
    grid: ParticleGrid,
    h_nodes: np.ndarray,
    u_nodes: np.ndarray,
    v_nodes: np.ndarray,
    per_direction: int,
) -> Particles:
    """Seed ``per_direction²`` particles in every owned cell where the initial depth is positive.

    Particles sit at the tensor Gauss–Legendre points of the cell with areas ``A_p = w_p |K|``;
    depth and velocity are the Q1 interpolants of the nodal initial fields, so
    ``V_p = A_p h_h(x_p)``. With two or more points per direction the particle quadrature is
    exact for ``∫ φ_i φ_j``: the consistent L2 projection of the particle volumes returns the
    nodal initial depth exactly (see :mod:`mpm.projection`).

    Args:
        grid: The particle grid.
        h_nodes: Nodal initial depth (local, with ghosts).
        u_nodes: Nodal initial x-velocity.
        v_nodes: Nodal initial y-velocity.
        per_direction: Particles per cell per direction.

    Returns:
        The particles of this rank (cells without depth get none).
    """
    ref, wxy = basix.make_quadrature(basix.CellType.quadrilateral, 2 * per_direction - 1)
    gx, gy = ref[:, 0], ref[:, 1]  # the Gauss points DOLFINx integrates the mass matrix with
    index = grid.owned_cells()
    n_loc = per_direction**2
    xi, eta = np.tile(gx.ravel(), index.size), np.tile(gy.ravel(), index.size)
    cell = np.repeat(index, n_loc)
    area = np.tile(wxy * grid.dx * grid.dy, index.size)
    pid = (index[:, None] * n_loc + np.arange(n_loc)[None, :]).ravel()
    basis = grid.basis(cell, xi, eta)
    h = interpolate(basis.nodes, basis.N, h_nodes)
    keep = h > 0.0
    u = interpolate(basis.nodes, basis.N, u_nodes)[keep]
    v = interpolate(basis.nodes, basis.N, v_nodes)[keep]
    zero = np.zeros(int(keep.sum()))
    return Particles(xi=xi[keep], eta=eta[keep], volume=area[keep] * h[keep], h=h[keep], u=u,
                     v=v, sxx=zero, syy=zero.copy(), sxy=zero.copy(),
                     cell=cell[keep].astype(np.int64), id=pid[keep].astype(np.int64))
