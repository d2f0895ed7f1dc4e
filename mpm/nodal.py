"""The global structured node array on which DAMPM does its grid work.

A GIMP domain (:mod:`mpm.gimp`) reaches the nodes of the neighbouring cells, diagonal ones
included, which need not be on the particle's rank. DAMPM therefore indexes its nodes by their
structured index ``j (nx + 1) + i`` on the whole grid, sums its particle-to-grid transfers over
the ranks on the nodes some rank touched (:mod:`mpm.exchange`), keeps the sums on the nodes
with mass (:class:`GridSums`), and each rank updates the nodes its own particles reach (node by
node: the same bits whatever the split). The DOLFINx functions the outputs read are the local
view ``global[node_index]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from fem_runout.mesh import SIDE_NORMALS, Discretization, Side, zero_wall_normal
from fem_runout.physics.friction import FrictionLaw
from fem_runout.physics.friction.base import spend_capacity
from fem_runout.physics.slope import BedFrame, SlopeGeometry
from mpm.exchange import Box
from mpm.gimp import structured_nodes

__all__ = ["GridSums", "NodalGrid", "NodeBuffers", "friction_step", "no_faster_than",
           "open_side_push", "zero_wall_velocity"]


class NodeBuffers:
    """Global node arrays kept between steps; a write clears only what the last one wrote.

    The flow covers a few thousand of the grid's nodes: allocating and zeroing whole arrays
    every step cost as much as the work on the nodes, and grew with the DEM.

    Args:
        size: Length of the arrays.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self._arrays: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def put(self, name: str, index: np.ndarray, values: np.ndarray | float) -> np.ndarray:
        """Return array ``name`` with ``values`` at ``index``, zero elsewhere.

        The array is valid until the next :meth:`put` of the same name.
        """
        array, last = self._arrays.get(name, (None, None))
        if array is None:
            array = np.zeros(self.size)
        else:
            array[last] = 0.0
        array[index] = values
        self._arrays[name] = (array, np.asarray(index))
        return array


@dataclass
class GridSums:
    """P2G sums on the nodes that carry mass (the only nodes the nodal update touches).

    Attributes:
        act: Sorted global indices of the nodes with ``mass > 0``.
        g: (len(act), k) sums at those nodes (columns of :data:`mpm.kernels.P2G_COLUMNS`).
        n_nodes: Size of the global node array.
        index: Positions of :attr:`act` in the node list the sums came from.
    """

    act: np.ndarray
    g: np.ndarray
    n_nodes: int
    index: np.ndarray
    _located: dict = field(default_factory=dict, repr=False, compare=False)

    def full(self, values: np.ndarray) -> np.ndarray:
        """Global array with ``values`` at :attr:`act`, zero elsewhere."""
        out = np.zeros(self.n_nodes)
        out[self.act] = values
        return out

    def restrict(self, lo: float, hi: float) -> GridSums:
        """Return the sums on the nodes ``lo <= i < hi`` (a view)."""
        a, b = np.searchsorted(self.act, [lo, hi])
        return GridSums(self.act[a:b], self.g[a:b], self.n_nodes, self.index[a:b])

    def locate(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions in :attr:`act` of the global ``nodes`` that carry mass: ``(pos, which)``.

        Kept per ``nodes`` array (a side's: the walls are located several times a step with
        the same sums); the arrays returned must not be changed.
        """
        key = id(nodes)
        if key not in self._located:
            self._located[key] = (nodes, *self._locate(nodes))  # nodes held: its id not reused
        return self._located[key][1:]

    def _locate(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pos = np.searchsorted(self.act, nodes)
        inside = pos < self.act.size
        hit = np.zeros(nodes.size, dtype=bool)
        hit[inside] = self.act[pos[inside]] == nodes[inside]
        return pos[hit], np.flatnonzero(hit)


class NodalGrid:
    """Global structured node arrays of a :class:`Discretization`.

    On a gmsh mesh the global numbering is the mesh grid's (:class:`mpm.mesh_grid.
    MeshParticleGrid`, nodes sorted by ``(y, x)``), and a P2G box is a range of it.

    Args:
        disc: The discretization.
        grid: The particle grid (its numbering is used on a gmsh mesh).
    """

    def __init__(self, disc: Discretization, grid=None) -> None:
        self.comm = disc.comm
        self._n_owned = disc.n_owned_nodes
        if not disc.structured:
            self.n_nodes = self.row_length = grid.n_nodes
            self.node_index = grid.node_index
            self.sides = grid.sides
        else:
            self.cells = tuple(disc.cells)
            self.spacing = tuple(disc.spacing)
            nx, ny = self.cells
            self.n_nodes = (nx + 1) * (ny + 1)
            self.row_length = nx + 1
            self.node_index = structured_nodes(disc.coords, disc.extent, disc.spacing,
                                               disc.cells)
            self.sides = [self._side(s.name, s.kind, SIDE_NORMALS[s.name]) for s in disc.sides]
        self._owned = self.node_index[: disc.n_owned_nodes]

    def _side(self, name: str, kind: str, normal: np.ndarray) -> Side:
        """Return a side with structured node indices and its ``∫ φ_i ds`` weights."""
        nx, ny = self.cells
        dx, dy = self.spacing
        if name in ("left", "right"):
            col = 0 if name == "left" else nx
            nodes, step, n = np.arange(ny + 1) * (nx + 1) + col, dy, ny
        else:
            row = 0 if name == "bottom" else ny
            nodes, step, n = row * (nx + 1) + np.arange(nx + 1), dx, nx
        weight = np.full(n + 1, step)
        weight[[0, -1]] = 0.5 * step
        return Side(name, kind, np.asarray(normal, float), nodes, weight)

    def sum(self, local: np.ndarray) -> np.ndarray:
        """Sum per-rank contributions on the global array over the ranks (collective)."""
        if self.comm.size > 1:
            self.comm.Allreduce(MPI.IN_PLACE, local, op=MPI.SUM)
        return local

    def box(self, bounds: np.ndarray) -> Box:
        """Return the box of nodes ``-min row, max row, -min column, max column`` (-inf: none)."""
        if not np.isfinite(bounds[1]):
            return Box(0, 0, 0, 0, self.row_length)
        j0, i0 = int(-bounds[0]), int(-bounds[2])
        return Box(j0, i0, int(bounds[1]) - j0 + 1, int(bounds[3]) - i0 + 1, self.row_length)

    def with_mass(self, nodes: np.ndarray, sums: np.ndarray) -> GridSums:
        """Return the sums on the nodes with ``mass > 0`` (first column) of sums on ``nodes``."""
        inner = np.flatnonzero(sums[:, 0] > 0.0)
        return GridSums(nodes[inner], sums[inner], self.n_nodes, inner)

    def to_global(self, values: np.ndarray) -> np.ndarray:
        """Global array of a local nodal array (owned entries; collective)."""
        out = np.zeros(self.n_nodes)
        out[self._owned] = values[: self._n_owned]
        return self.sum(out)

    def geometry_to_global(self, slope: SlopeGeometry) -> SlopeGeometry:
        """Return a bed geometry on the global node array (collective)."""
        def glob(a: np.ndarray) -> np.ndarray:
            return np.stack([self.to_global(np.ascontiguousarray(a[:, k]))
                             for k in range(a.shape[1])], axis=1)
        return SlopeGeometry(glob(slope.grad), glob(slope.hess), slope.g, slope.curvature)

    def to_local(self, values: np.ndarray) -> np.ndarray:
        """Return the local (owned + ghost) view of a global array."""
        return values[self.node_index]


def friction_step(friction: FrictionLaw, h: np.ndarray, vx: np.ndarray, vy: np.ndarray,
                  ax: np.ndarray, ay: np.ndarray, dt: float, bed: BedFrame | None,
                  walls) -> tuple[np.ndarray, np.ndarray]:
    """Nodal velocity after Strang's ``F(dt/2) D(dt) F(dt/2)``: forces ``a``, friction ``D``.

    ``v`` is the velocity after the first half of the forces (walls applied), ``a`` the
    velocity change of a half (``Δt/2 f_i/M_i``); ``D`` is :meth:`FrictionLaw.integrate` on
    the momentum ``h v`` with the nodal depth ``h``, and the yield capacity it leaves holds
    the second half (:meth:`FrictionLaw.unused_capacity`), as in TG2-PC's step. Lie's
    ``D(dt) F(dt)`` with one backward-Euler solve was first order: the Voellmy sheet's speed
    was 1.7e-4 off at 400 steps where this gives 2e-6 (docs/dampm.md). ``walls(vx, vy)``
    zeroes the wall-normal velocity in place. Zero where ``h = 0``.
    """
    qx, qy = h * vx, h * vy
    rest = friction.unused_capacity(h, qx, qy, dt, bed)
    qx, qy = friction.integrate(h, qx, qy, dt, bed)
    qx, qy = qx + h * ax, qy + h * ay
    walls(qx, qy)
    if rest is not None:
        qx, qy = spend_capacity(qx, qy, rest)
    hs = np.where(h > 0, h, 1.0)
    return np.where(h > 0, qx / hs, 0.0), np.where(h > 0, qy / hs, 0.0)


def no_faster_than(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray,
                   by: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``a`` scaled by ``|b| / max(|a|, |b|)`` (``a`` where ``|a| <= |b|``, 0 at ``b = 0``).

    Continuous in both (no switch): DAMPM's strain velocity against the friction-updated
    nodal velocity (material friction holds does not deform).
    """
    speed = np.hypot(bx, by)
    top = np.maximum(np.hypot(ax, ay), speed)
    scale = np.divide(speed, top, out=np.ones_like(top), where=top > 0.0)
    return ax * scale, ay * scale


def zero_wall_velocity(walls: list[Side], sums: GridSums, vx: np.ndarray,
                       vy: np.ndarray) -> None:
    """Zero the wall-normal velocity at the walls' nodes with mass (in place).

    ``vx, vy`` are at ``sums.act``. A side of the rectangle zeroes one component; a gmsh
    mesh's wall nodes lose ``(v·n) n`` with their own normal (both components at corners).
    """
    for side in walls:
        pos, which = sums.locate(side.nodes)
        if side.normal.ndim == 1:
            (vx if side.normal[0] != 0.0 else vy)[pos] = 0.0
        else:
            zero_wall_normal([side.take(which, pos)], vx, vy)


def open_side_push(open_sides: list[Side], sums: GridSums, h: np.ndarray,
                   still: np.ndarray | None, half_rho_g: float, fx: np.ndarray,
                   fy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Add the pressure of the fluid beyond open sides: a transmissive boundary.

    The boundary term of eq. 28, ``∫ σ^∇ h φ_i n ds``, with the outside state equal to the
    boundary node's: ``-½ ρ g (h_i² - H_i²) ∫φ_i ds n``. The seed's zero traction makes an
    open side a free edge (a reservoir touching it drains into vacuum); with this term an
    open side lets the flow out like TG2-PC's outflow boundary and holds a layer at rest.
    ``fx, fy`` are at the nodes with mass (``sums.act``); ``h`` and ``still`` (``H``, or None)
    on the global node array. Returns new arrays.
    """
    fx, fy = fx.copy(), fy.copy()
    for side in open_sides:
        pos, which = sums.locate(side.nodes)
        if which.size == 0:
            continue  # no mass at the side (the usual step: a dozen array formulas less)
        nodes = side.nodes[which]
        hb = h[nodes]
        big = 0.0 if still is None else still[nodes]
        push = half_rho_g * (hb * hb - big * big) * side.weight[which]
        n = side.normal if side.normal.ndim == 1 else side.normal[which].T
        fx[pos] -= push * n[0]
        fy[pos] -= push * n[1]
    return fx, fy
