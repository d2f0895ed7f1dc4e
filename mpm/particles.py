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

__all__ = ["AFFINE_FIELDS", "FLOAT_FIELDS", "QUAD_FIELDS", "Particles", "seed_particles"]

#: Corner offsets of a particle's quadrilateral domain on a gmsh mesh.
QUAD_FIELDS = ("q0x", "q0y", "q1x", "q1y", "q2x", "q2y", "q3x", "q3y")
#: APIC's affine velocity ``C_p``.
AFFINE_FIELDS = ("cxx", "cxy", "cyx", "cyy")
#: Per-particle float arrays (the ``id`` is int64), as :meth:`Particles.pack` orders them.
FLOAT_FIELDS = ("xi", "eta", "lx", "ly", "volume", "h", "u", "v", "sxx", "syy", "sxy",
                *AFFINE_FIELDS, *QUAD_FIELDS)


@dataclass
class Particles:
    """Particle state as flat arrays of equal length.

    Attributes:
        xi, eta: Reference coordinates in the cell, in [0, 1].
        lx, ly: Half-widths of the particle's domain [m] (:mod:`mpm.gimp`), stretched with
            the flow; splitting keeps them at most half a cell (:mod:`mpm.split`).
        volume: ``V_p = m_p/ρ`` [m³] (fixed).
        h: Depth ``h_p`` [m] (seed eq. 42).
        u, v: Velocity [m/s].
        sxx, syy, sxy: Depth-averaged deviatoric stress ``σ_p`` [Pa] (seed eq. 41).
        cell: Structured cell index ``j nx + i``.
        id: Global particle id.
        cxx, cxy, cyx, cyy: Affine velocity ``C_p`` of APIC [1/s] (``C_ab = ∂v_a/∂x_b`` of
            the grid velocity at the particle), or None: zero (the FLIP transfer).
        q0x, q0y, .. q3x, q3y: On a gmsh mesh, the corners of the particle's domain, a convex
            quadrilateral, as offsets from the particle [m] (counter-clockwise; all zero: a
            point particle; :mod:`mpm.mesh_clip`), or None: point particles (the grid).
    """

    xi: np.ndarray
    eta: np.ndarray
    lx: np.ndarray
    ly: np.ndarray
    volume: np.ndarray
    h: np.ndarray
    u: np.ndarray
    v: np.ndarray
    sxx: np.ndarray
    syy: np.ndarray
    sxy: np.ndarray
    cell: np.ndarray
    id: np.ndarray
    cxx: np.ndarray | None = None
    cxy: np.ndarray | None = None
    cyx: np.ndarray | None = None
    cyy: np.ndarray | None = None
    q0x: np.ndarray | None = None
    q0y: np.ndarray | None = None
    q1x: np.ndarray | None = None
    q1y: np.ndarray | None = None
    q2x: np.ndarray | None = None
    q2y: np.ndarray | None = None
    q3x: np.ndarray | None = None
    q3y: np.ndarray | None = None

    def with_fields(self, affine: bool, quad: bool) -> Particles:
        """Return these particles carrying the optional groups asked for (shares the arrays).

        A group not carried is None (no memory, nothing copied by :meth:`copy`,
        :meth:`select`, ...); a group added starts at zero. The solver carries ``C_p`` only
        with APIC and the corners only on a gmsh mesh: on the grid without APIC, 12 of the 25
        columns were zeros copied on every step (snapshot, splitting, migration).
        """
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        for names, on in ((AFFINE_FIELDS, affine), (QUAD_FIELDS, quad)):
            for name in names:
                if not on:
                    data[name] = None
                elif data[name] is None:
                    data[name] = np.zeros(self.xi.size)
        return Particles(**data)

    @property
    def has_affine(self) -> bool:
        """Whether the particles carry APIC's ``C_p`` (else it is zero)."""
        return self.cxx is not None

    @property
    def has_quad(self) -> bool:
        """Whether the particles carry quadrilateral domains (else they are points)."""
        return self.q0x is not None

    def __len__(self) -> int:
        return int(self.xi.size)

    def positions(self, grid: ParticleGrid) -> tuple[np.ndarray, np.ndarray]:
        """Physical coordinates ``(x, y)`` [m]."""
        return grid.positions(self.cell, self.xi, self.eta)

    @property
    def area(self) -> np.ndarray:
        """Column area ``A_p = V_p / h_p`` [m²]."""
        return self.volume / self.h

    def quad(self) -> np.ndarray:
        """(n, 8) the domain's corner offsets ``q0x, q0y, .. q3x, q3y`` (zeros: points)."""
        if not self.has_quad:
            return np.zeros((len(self), len(QUAD_FIELDS)))
        return self.quad_at(slice(None))

    def set_quad(self, quad: np.ndarray) -> None:
        """Set the corner offsets from an (n, 8) array."""
        for k, name in enumerate(QUAD_FIELDS):
            setattr(self, name, np.ascontiguousarray(quad[:, k]))

    def quad_columns(self) -> tuple[np.ndarray, ...]:
        """Return the eight corner-offset arrays themselves (no copy; kernels may change them)."""
        if not self.has_quad:
            return tuple(np.zeros(len(self)) for _ in QUAD_FIELDS)
        for name in QUAD_FIELDS:  # one array type for the kernels' tuple
            if not getattr(self, name).flags.c_contiguous:
                setattr(self, name, np.ascontiguousarray(getattr(self, name)))
        return tuple(getattr(self, name) for name in QUAD_FIELDS)

    def quad_at(self, idx: np.ndarray | slice) -> np.ndarray:
        """(len(idx), 8) the corner offsets of particles ``idx``."""
        return np.stack([getattr(self, name)[idx] for name in QUAD_FIELDS], axis=1)

    def set_quad_at(self, idx: np.ndarray, quad: np.ndarray) -> None:
        """Set the corner offsets of particles ``idx`` from a (len(idx), 8) array (in place)."""
        for k, name in enumerate(QUAD_FIELDS):
            getattr(self, name)[idx] = quad[:, k]

    def affine(self) -> np.ndarray:
        """(4, n) affine velocities ``C_xx, C_xy, C_yx, C_yy`` (APIC; zeros without it).

        Without APIC the zeros are one shared array per size (the kernels only read it; the
        P2G and the next step's MUSL sums take it for the same particles).
        """
        if not self.has_affine:
            return _zero_rows(len(AFFINE_FIELDS), len(self))
        return np.stack([self.cxx, self.cxy, self.cyx, self.cyy])

    def transfer_speeds(self, dx: float, dy: float, apic: bool
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the velocity a particle gives its nodes: ``|u|, |v|`` without APIC.

        With APIC ``|v_p| + 2 (Δx |C_x.| + Δy |C_.y|)``: a particle's nodes lie within two
        cells of its domain's centre. They set the exact sums' extractors.
        """
        if not apic or not self.has_affine:
            return self.u, self.v
        return (np.abs(self.u) + 2.0 * (dx * np.abs(self.cxx) + dy * np.abs(self.cxy)),
                np.abs(self.v) + 2.0 * (dx * np.abs(self.cyx) + dy * np.abs(self.cyy)))

    def copy(self) -> Particles:
        """Deep copy."""
        return Particles(**{f.name: _copy(getattr(self, f.name)) for f in fields(self)})

    def copy_into(self, store: dict[str, np.ndarray] | None) -> tuple[Particles, dict]:
        """Copy into the arrays of ``store`` (grown when too small); return the copy and store.

        A copy made every step (the runner's last good state) reuses its memory instead of
        allocating (and page-faulting) some MB per step. The copy is valid until the next
        call with the same store.
        """
        n = len(self)
        store = {} if store is None else store
        out = {}
        for f in fields(self):
            mine = getattr(self, f.name)
            if mine is None:
                out[f.name] = None
                continue
            buf = store.get(f.name)
            if buf is None or buf.size < n:
                buf = store[f.name] = np.empty(max(n, int(1.25 * n)), dtype=mine.dtype)
            out[f.name] = buf[:n]
            out[f.name][:] = mine
        return Particles(**out), store

    def select(self, mask: np.ndarray) -> Particles:
        """Return the particles where ``mask`` is true (or at the given indices)."""
        return Particles(**{f.name: _take(getattr(self, f.name), mask) for f in fields(self)})

    def pack(self) -> np.ndarray:
        """(n, 25) float64 rows for MPI exchange (cell and id stored exactly as float64 views).

        A group not carried is written as zeros (:meth:`with_fields`).
        """
        out = np.empty((len(self), len(FLOAT_FIELDS) + 2))
        for k, name in enumerate(FLOAT_FIELDS):
            mine = getattr(self, name)
            out[:, k] = 0.0 if mine is None else mine
        out[:, -2] = self.cell.view(np.float64)
        out[:, -1] = self.id.view(np.float64)
        return out

    @classmethod
    def unpack(cls, rows: np.ndarray, affine: bool = True, quad: bool = True) -> Particles:
        """Inverse of :meth:`pack`; also reads the 13- and 17-column rows of older checkpoints.

        Rows from before APIC get ``C_p = 0``; rows from before the quadrilateral domains get
        point domains on a gmsh mesh (on the grid the corners are unused). ``affine``,
        ``quad``: the optional groups to carry (:meth:`with_fields`).
        """
        rows = np.ascontiguousarray(rows)
        for old, missing in ((13, 4), (17, len(QUAD_FIELDS))):
            if rows.ndim == 2 and rows.shape[1] == old:
                rows = np.concatenate([rows[:, :-2], np.zeros((rows.shape[0], missing)),
                                       rows[:, -2:]], axis=1)
        rows = rows.reshape(-1, len(FLOAT_FIELDS) + 2)
        skip = (() if affine else AFFINE_FIELDS) + (() if quad else QUAD_FIELDS)
        data = {name: None if name in skip else rows[:, k].copy()
                for k, name in enumerate(FLOAT_FIELDS)}
        cell = np.ascontiguousarray(rows[:, -2]).view(np.int64).copy()
        return cls(**data, cell=cell, id=np.ascontiguousarray(rows[:, -1]).view(np.int64).copy())

    def select_and_append(self, keep: np.ndarray, other: Particles) -> Particles:
        """Return the particles where ``keep`` is true followed by ``other`` (one copy)."""
        n = int(np.count_nonzero(keep))
        out = {}
        for f in fields(self):
            mine, theirs = getattr(self, f.name), getattr(other, f.name)
            if mine is None or theirs is None:
                if (mine is None) != (theirs is None):
                    raise ValueError(f"particle sets differ in carrying {f.name}")
                out[f.name] = None
                continue
            joined = np.empty(n + theirs.size, dtype=mine.dtype)
            np.compress(keep, mine, out=joined[:n])
            joined[n:] = theirs
            out[f.name] = joined
        return Particles(**out)

    @classmethod
    def concatenate(cls, parts: list[Particles]) -> Particles:
        """Join several particle sets."""
        return cls(**{f.name: _join([getattr(p, f.name) for p in parts], f.name)
                      for f in fields(cls)})


_ZERO_ROWS: dict[tuple[int, int], np.ndarray] = {}


def _zero_rows(rows: int, n: int) -> np.ndarray:
    """Return a (rows, n) array of zeros that nothing writes to (the last one of its size)."""
    key = (rows, n)
    if key not in _ZERO_ROWS:
        _ZERO_ROWS.clear()
        _ZERO_ROWS[key] = np.zeros(key)
    return _ZERO_ROWS[key]


def _copy(a: np.ndarray | None) -> np.ndarray | None:
    """Copy of an optional array."""
    return None if a is None else a.copy()


def _take(a: np.ndarray | None, mask: np.ndarray) -> np.ndarray | None:
    """``a[mask]`` of an optional array."""
    return None if a is None else a[mask]


def _join(arrays: list[np.ndarray | None], name: str) -> np.ndarray | None:
    """Concatenation of optional arrays (all None or none None)."""
    missing = sum(a is None for a in arrays)
    if missing == len(arrays):
        return None
    if missing:
        raise ValueError(f"particle sets differ in carrying {name}")
    return np.concatenate(arrays)


def seed_particles(
    grid: ParticleGrid,
    h_nodes: np.ndarray,
    u_nodes: np.ndarray,
    v_nodes: np.ndarray,
    per_direction: int,
    layout: str = "uniform",
    min_depth: float = 0.0,
) -> Particles:
    """Seed up to ``per_direction²`` particles in every owned cell with depth above ``min_depth``.

    ``uniform``: particles at the centres of the ``n × n`` sub-cells, areas ``|K|/n²`` and
    domains equal to the sub-cells (they tile the material; the lattice is alias-free on the
    grid, which makes DAMPM converge at first order on Ritter's dam break, docs/dampm.md).
    On a gmsh mesh the sub-cells are the images of the reference ones, the particles sit at
    their centroids and carry them as quadrilateral domains (:mod:`mpm.mesh_clip`).
    ``gauss``: particles at the tensor Gauss–Legendre points with areas ``A_p = w_p |K|``:
    with two or more points per direction the particle quadrature is exact for ``∫ φ_i φ_j``,
    so the consistent L2 projection of the particle volumes returns the nodal initial depth
    exactly (the lake at rest, :mod:`mpm.projection`); domain half-widths ``Δ/(2 n)`` cut to
    the distance to the cell's edge, so the GIMP weights start as the point values.
    Depth and velocity are the Q1 interpolants of the nodal initial fields, so
    ``V_p = A_p h_h(x_p)`` (for ``uniform`` the exact volume of the sub-cell). Points where
    ``h_h(x_p) <= min_depth`` (the dry tolerance) get no particle: a near-massless particle
    at a shoreline carries no information, but its velocity (a FLIP update from nodes with no
    mass) is erratic and it would set the time step. The volume not seeded is at most
    ``min_depth`` times the dry part of the cells' area; the released volume that runs report
    is the particles' (their projection conserves it exactly).

    Args:
        grid: The particle grid.
        h_nodes: Nodal initial depth (local, with ghosts).
        u_nodes: Nodal initial x-velocity.
        v_nodes: Nodal initial y-velocity.
        per_direction: Particles per cell per direction.
        layout: ``"uniform"`` (sub-cell centres) or ``"gauss"`` (Gauss points).
        min_depth: No particle where the interpolated depth is at most this [m].

    Returns:
        The particles of this rank (cells without depth get none).
    """
    ref, wxy = basix.make_quadrature(basix.CellType.quadrilateral, 2 * per_direction - 1)
    gx, gy = ref[:, 0], ref[:, 1]  # the Gauss points DOLFINx integrates the mass matrix with
    if layout == "uniform":  # sub-cell centres, in the same order as basix's points
        centre = (np.arange(per_direction) + 0.5) / per_direction
        gx, gy = (np.searchsorted(np.unique(a), a) for a in (ref[:, 0], ref[:, 1]))
        gx, gy = centre[gx], centre[gy]
        wxy = np.full(per_direction**2, 1.0 / per_direction**2)
    elif layout != "gauss":
        raise ValueError(f"unknown particle layout {layout!r} (allowed: gauss, uniform)")
    index = grid.owned_cells()
    n_loc = per_direction**2
    xi, eta = np.tile(gx.ravel(), index.size), np.tile(gy.ravel(), index.size)
    cell = np.repeat(index, n_loc)
    area = grid.areas(cell, xi, eta, np.tile(wxy, index.size))
    quad = None
    if not grid.structured and layout == "uniform":  # the sub-cells, centroids, exact areas
        xi, eta, area, quad = grid.seed_domains(cell, xi, eta, per_direction)
    pid = (index[:, None] * n_loc + np.arange(n_loc)[None, :]).ravel()
    basis = grid.basis(cell, xi, eta)
    h = interpolate(basis.nodes, basis.N, h_nodes)
    keep = h > min_depth
    u = interpolate(basis.nodes, basis.N, u_nodes)[keep]
    v = interpolate(basis.nodes, basis.N, v_nodes)[keep]
    zero = np.zeros(int(keep.sum()))
    if grid.structured:
        lx, ly = (np.minimum(0.5 / per_direction, np.minimum(r, 1.0 - r)[keep]) * d
                  for r, d in ((xi, grid.dx), (eta, grid.dy)))
    else:  # the sub-cell as a quadrilateral domain; Gauss points: point particles
        lx, ly = zero.copy(), zero.copy()
    out = Particles(xi=xi[keep], eta=eta[keep], lx=lx, ly=ly, volume=area[keep] * h[keep],
                    h=h[keep], u=u, v=v, sxx=zero, syy=zero.copy(), sxy=zero.copy(),
                    cell=cell[keep].astype(np.int64), id=pid[keep].astype(np.int64))
    if quad is not None:
        out.set_quad(quad[keep])
    return out
