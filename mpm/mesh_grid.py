"""DAMPM's background grid on an unstructured quadrilateral mesh (issue 17).

On a gmsh mesh there is no index arithmetic: every rank keeps the whole mesh's topology in a
partition-independent numbering (a few MB for 1e5 cells, like the structured code's global node
array), and a particle is a cell of that numbering plus its reference coordinates ``(ξ, η)``
in the cell's bilinear map

    x(ξ, η) = x_0 + e_1 ξ + e_2 η + c ξ η,    e_1 = x_1 - x_0, e_2 = x_2 - x_0,
    c = x_0 - x_1 - x_2 + x_3

(basix order of the corners ``(0,0), (1,0), (0,1), (1,1)``). The numbering:

- nodes sorted by ``(y, x)`` of their coordinates (input bits, the same on every rank);
- cells sorted by their centre's ``(y, x)``, so that consecutive cells make strips of the
  domain (the balanced split of :mod:`mpm.migrate` and compact node ranges per rank);
- every cell's corners rotated so that its first corner is its smallest node, the second its
  smaller neighbour of the first: the reference frame does not depend on DOLFINx's ordering.

A displacement is solved for in the cell's own frame, relative to the current point (a particle
at rest keeps its exact ``(ξ, η)``, so the lake at rest stays exact); a particle that leaves the
cell walks across the edge it leaves by (:func:`mpm.mesh_locate.walk`, the neighbour table),
leaves the domain through an open edge, or stops on a wall edge. The weights at the particles
are GIMP's domain averages (:func:`mpm.mesh_weights.domain_basis`); a particle's domain
half-widths ``l_x, l_y`` are along its cell's ξ and η axes.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.mesh import Discretization, Side
from fem_runout.quadmesh import EDGE_CORNERS, KIND_CODES
from mpm.grid import Basis
from mpm.mesh_clip import cost_estimate, seed_quads
from mpm.mesh_locate import WALK_EDGES, jacobian_det, walk
from mpm.mesh_weights import domain_basis, domain_scratch, point_basis
from mpm.weight_reuse import PreviousWeights

__all__ = ["MeshBasis", "MeshParticleGrid", "crossing_lengths"]


def _canonical(corners: np.ndarray) -> np.ndarray:
    """Rotate/reflect each cell's corners: smallest node first, its smaller neighbour second."""
    cycle = corners[:, [0, 1, 3, 2]]
    s = np.argmin(cycle, axis=1)
    rows = np.arange(corners.shape[0])
    nxt, prv = cycle[rows, (s + 1) % 4], cycle[rows, (s + 3) % 4]
    step = np.where(nxt < prv, 1, 3)
    c = np.stack([cycle[rows, (s + t * step) % 4] for t in range(4)], axis=1)
    return np.ascontiguousarray(c[:, [0, 1, 3, 2]])


def _gather(comm: MPI.Comm, local: np.ndarray) -> np.ndarray:
    """Concatenate every rank's rows (collective), in rank order."""
    parts = comm.allgather(np.ascontiguousarray(local))
    return np.concatenate(parts) if parts else local


def crossing_lengths(coords: np.ndarray, corners: np.ndarray, neighbour: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Return the CFL length of each cell's particles (:func:`mpm.step_limits.crossing_time`).

    A cell's length is ``sqrt(2) |K| / d_max`` (``d_max`` its longer diagonal): ``Δx`` on a
    square, and on a rectangle ``a × b`` the length ``sqrt(2) / sqrt(1/a² + 1/b²)`` whose
    ratio to the square's is that of the two cells' explicit wave steps with lumped mass; a
    skewed cell (one long diagonal) gets less than its shortest edge.

    Args:
        coords: (n_nodes, 2) node coordinates.
        corners: (n_cells, 4) corner nodes, lexicographic (``(0,0), (1,0), (0,1), (1,1)``).
        neighbour: (n_cells, 4) neighbouring cells across the sides (-1: none).

    Returns:
        ``(own, around)``: every cell's length, and the smallest over the cell and the cells
        across its sides (for a particle whose domain reaches beyond its cell).
    """
    x = coords[corners]
    d1, d2 = x[:, 3] - x[:, 0], x[:, 2] - x[:, 1]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    longest = np.sqrt(np.maximum((d1**2).sum(axis=1), (d2**2).sum(axis=1)))
    own = np.sqrt(2.0) * area / longest
    around = np.where(neighbour >= 0, own[np.maximum(neighbour, 0)], np.inf)
    return own, np.minimum(own, around.min(axis=1))


class MeshParticleGrid:
    """Locate particles on an unstructured quadrilateral mesh; the mesh in a global numbering.

    The same interface as :class:`mpm.grid.ParticleGrid` (see the module docstring).

    Args:
        disc: The discretization of a gmsh mesh (``disc.edges`` set).
    """

    structured = False
    #: the strip units are bands of cells: the particles' own costs weigh them (balance_weights)
    unit_cost = 0

    def __init__(self, disc: Discretization) -> None:
        self.disc, self.comm = disc, disc.comm
        comm, n_own = disc.comm, disc.n_owned_nodes
        imap = disc.V.dofmap.index_map
        n_local = disc.coords.shape[0]
        gidx = np.asarray(imap.local_to_global(np.arange(n_local, dtype=np.int32)), np.int64)
        rows = _gather(comm, np.column_stack([gidx[:n_own].astype(float), disc.coords[:n_own]]))
        order = np.lexsort((rows[:, 1], rows[:, 2]))
        sorted_of = np.empty(rows.shape[0], dtype=np.int64)
        sorted_of[rows[order, 0].astype(np.int64)] = np.arange(rows.shape[0])
        self.coords = np.ascontiguousarray(rows[order, 1:])
        self.n_nodes = self.coords.shape[0]
        #: global (sorted) node of every local node, owned then ghosts
        self.node_index = sorted_of[gidx]
        self._local_of = np.full(self.n_nodes, -1, dtype=np.int64)
        self._local_of[self.node_index] = np.arange(n_local)
        self._cells(disc)
        self._neighbours(disc)
        self.sides = self._global_sides(disc)
        self.min_size = float(disc.min_cell_size)
        edge = self.coords[self.corners[:, WALK_EDGES[:, 1]]] - self.coords[
            self.corners[:, WALK_EDGES[:, 0]]]
        # the reach of a particle's nodes for APIC's bounds (``2 Δx`` in
        # Particles.transfer_speeds): half a domain's diagonal (<= 0.71 of the longest edge)
        # plus a cell's diagonal (<= 2 edges) is below 3 longest edges, so Δx = 1.5 of it
        self.dx = self.dy = 1.5 * float(np.sqrt((edge**2).sum(axis=-1)).max())
        self.cell_size, self.local_size = crossing_lengths(self.coords, self.corners,
                                                           self.neighbour)
        self.nx, self.n_rows = 1, max(1, int(np.sqrt(self.n_cells)))
        # the domain weights' buffers, kept between steps (:meth:`particle_basis`): two sets,
        # alternating, so that the last step's weights can be copied for particles at rest
        self._sets = [_weight_buffers(0), _weight_buffers(0)]
        self._previous = PreviousWeights()
        self._scratch = domain_scratch()  # the weights loop's, reused every step

    def _cells(self, disc: Discretization) -> None:
        """Global cells (sorted by centre), canonical corners, owners and the bilinear maps."""
        comm, n_own = self.comm, disc.n_owned_cells
        corners = _canonical(self.node_index[disc.cell_nodes[:n_own]])
        local = np.column_stack([corners, np.full(n_own, comm.rank), np.arange(n_own)])
        allc = _gather(comm, local.astype(np.int64))
        centre = self.coords[allc[:, :4]].mean(axis=1)
        order = np.lexsort((allc[:, 0], centre[:, 0], centre[:, 1]))
        allc = allc[order]
        self.n_cells = allc.shape[0]
        self.corners = np.ascontiguousarray(allc[:, :4])
        self.owner = np.ascontiguousarray(allc[:, 4].astype(np.int32))
        mine = np.flatnonzero(self.owner == comm.rank)
        self.local_cell = np.full(self.n_cells, -1, dtype=np.int64)
        self.local_cell[mine] = allc[mine, 5]
        self._owned = np.empty(n_own, dtype=np.int64)
        self._owned[allc[mine, 5]] = mine
        x = self.coords[self.corners]
        self.origin = np.ascontiguousarray(x[:, 0])
        self.geo = np.ascontiguousarray(np.concatenate(
            [x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 0] - x[:, 1] - x[:, 2] + x[:, 3]],
            axis=1))

    def _neighbours(self, disc: Discretization) -> None:
        """Cell across each edge (walk order) and the boundary kind of edges without one."""
        n = self.n_nodes
        own = disc.n_owned_cells
        k, e = np.nonzero(disc.edges.kind[:own] > 0)
        a = self.node_index[disc.cell_nodes[k, EDGE_CORNERS[e, 0]]]
        b = self.node_index[disc.cell_nodes[k, EDGE_CORNERS[e, 1]]]
        bnd = _gather(self.comm, np.column_stack(
            [np.minimum(a, b) * n + np.maximum(a, b), disc.edges.kind[k, e]]).astype(np.int64))
        bnd = bnd[np.argsort(bnd[:, 0], kind="stable")]
        pa, pb = self.corners[:, WALK_EDGES[:, 0]], self.corners[:, WALK_EDGES[:, 1]]
        key = (np.minimum(pa, pb) * n + np.maximum(pa, pb)).ravel()
        order = np.argsort(key, kind="stable")
        ks = key[order]
        same = np.flatnonzero(ks[1:] == ks[:-1])
        neighbour = np.full(key.size, -1, dtype=np.int64)
        neighbour[order[same]] = order[same + 1] // 4
        neighbour[order[same + 1]] = order[same] // 4
        kind = np.zeros(key.size, dtype=np.int64)
        edge = np.flatnonzero(neighbour < 0)
        kind[edge] = KIND_CODES["wall"]
        if bnd.shape[0]:
            pos = np.minimum(np.searchsorted(bnd[:, 0], key[edge]), bnd.shape[0] - 1)
            hit = bnd[pos, 0] == key[edge]
            kind[edge[hit]] = bnd[pos[hit], 1]
        self.neighbour = neighbour.reshape(-1, 4)
        self.edge_kind = kind.reshape(-1, 4)

    def _global_sides(self, disc: Discretization) -> list[Side]:
        """Return the open and wall sides on global nodes (owned entries of every rank)."""
        out = []
        for side in disc.sides:
            own = side.nodes < disc.n_owned_nodes
            corner = np.zeros(side.nodes.size) if side.corner is None else side.corner
            rows = _gather(self.comm, np.column_stack(
                [self.node_index[side.nodes[own]], side.normal[own], side.weight[own],
                 corner[own]]).reshape(-1, 5))
            rows = rows[np.argsort(rows[:, 0], kind="stable")]
            out.append(Side(side.name, side.kind, np.ascontiguousarray(rows[:, 1:3]),
                            rows[:, 0].astype(np.int64), rows[:, 3],
                            None if side.corner is None else rows[:, 4] > 0.5))
        return out

    # -- the interface of ParticleGrid -----------------------------------------------------
    def owned_cells(self) -> np.ndarray:
        """Global indices of the cells this rank owns (local cell order)."""
        return self._owned

    def rows(self, cell: np.ndarray) -> np.ndarray:
        """Strip of each cell (cells are sorted by centre: strips across the domain)."""
        return cell * self.n_rows // self.n_cells

    def balance_weights(self, p) -> np.ndarray:
        """Per-particle cost for :func:`mpm.migrate.balanced_destinations` (integers).

        3, 6 or 9 (:func:`mpm.mesh_clip.cost_estimate` times 3): a domain across a side of its
        cell costs twice one inside (its weights cut two cells), one around a vertex three
        times; a particle at rest (``u = v = 0``) 2, as its weights are likely to be copied
        from the step before (:mod:`mpm.weight_reuse`), leaving the rest of its work (about
        two thirds of a moving particle's inside its cell, on the avaKot corridor).
        """
        cost = 3 * cost_estimate(self.geo, self.origin, np.ascontiguousarray(p.cell),
                                 np.ascontiguousarray(p.xi), np.ascontiguousarray(p.eta),
                                 p.quad())
        cost[(p.u == 0.0) & (p.v == 0.0)] = 2
        return cost

    def positions(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Physical coordinates of points given in cells."""
        g = self.geo[cell]
        o = self.origin[cell]
        return (o[:, 0] + g[:, 0] * xi + g[:, 2] * eta + g[:, 4] * xi * eta,
                o[:, 1] + g[:, 1] * xi + g[:, 3] * eta + g[:, 5] * xi * eta)

    def areas(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray,
              weights: np.ndarray) -> np.ndarray:
        """``w |det J|`` at the points: the area a quadrature weight stands for."""
        return weights * jacobian_det(self.geo, cell, xi, eta)

    def centre_jacobians(self) -> np.ndarray:
        """(n_cells, 4) ``x_ξ, x_η, y_ξ, y_η`` of every cell at its centre."""
        g = self.geo
        return np.stack([g[:, 0] + 0.5 * g[:, 4], g[:, 2] + 0.5 * g[:, 4],
                         g[:, 1] + 0.5 * g[:, 5], g[:, 3] + 0.5 * g[:, 5]], axis=1)

    def seed_domains(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray,
                     per_direction: int) -> tuple[np.ndarray, ...]:
        """Sub-cells centred at ``(ξ, η)`` as domains: ``(ξ_c, η_c, area, quad)``.

        See :func:`mpm.mesh_clip.seed_quads`: the particles move to the centroids.
        """
        return seed_quads(self.geo, np.ascontiguousarray(cell), np.ascontiguousarray(xi),
                          np.ascontiguousarray(eta), 0.5 / per_direction)

    def displace(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray, dx: np.ndarray,
                 dy: np.ndarray) -> tuple[np.ndarray, ...]:
        """Move points by ``(dx, dy)`` [m]: ``(cell, ξ, η, out, None)``.

        ``out``: left through an open edge (:func:`mpm.mesh_locate.walk`). The domains are
        physical quadrilaterals, so a new cell's axes swap nothing (the grid's last item).
        """
        return (*walk(self.geo, self.origin, self.neighbour, self.edge_kind,
                      np.ascontiguousarray(cell), np.ascontiguousarray(xi, dtype=float),
                      np.ascontiguousarray(eta, dtype=float), np.ascontiguousarray(dx, float),
                      np.ascontiguousarray(dy, float)), None)

    def basis(self, cell: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> Basis:
        """Q1 basis at points of this rank's owned cells, on local dofs (seeding)."""
        cells = self.local_cell[cell]
        if cells.size and cells.min() < 0:
            raise ValueError("a particle lies outside the cells owned by this rank")
        nodes, N, dN = point_basis(self.geo, self.corners, cell, xi, eta)
        return Basis(cells, self._local_of[nodes], N, dN)

    @property
    def transfers(self):
        """The point-basis kernels (:data:`mpm.transfers.POINT`)."""
        from mpm.transfers import POINT

        return POINT

    def crossing_sizes(self, p, basis: MeshBasis) -> np.ndarray:
        """Return the CFL length of each particle (:func:`crossing_lengths`).

        A domain inside its cell has its cell's four nodes only (:func:`domain_basis`) and
        takes its cell's length; one reaching further the smallest around its cell.
        """
        inside = np.diff(basis.arrays[0]) == 4
        return np.where(inside, self.cell_size[p.cell], self.local_size[p.cell])

    def particle_basis(self, p) -> MeshBasis:
        """Return the domain weights of particles ``p`` on global nodes (:func:`domain_basis`).

        A particle whose cell, ``(ξ, η)`` and domain have the bits they had in the last call
        (at rest) gets the last call's entries (the same bits as computing them; 16 % of the
        particle-steps of the avaKot corridor's run).
        """
        n = p.cell.size
        quad = p.quad()
        self._sets.reverse()  # the last call's set stays as it is until this call is done
        offsets, *buffers = self._sets[0]
        if offsets.size < n + 1:
            offsets = np.empty(2 * n + 1, dtype=np.int64)
        while True:
            used = domain_basis(self.geo, self.origin, self.corners, self.neighbour,
                                p.cell, p.xi, p.eta, quad, offsets, *buffers,
                                scratch=self._scratch, previous=self._previous,
                                ids=getattr(p, "id", None))
            if used >= 0:
                break
            buffers = _weight_buffers(2 * max(buffers[0].size, 8 * n))[1:]
        self._sets[0] = (offsets, *buffers)
        self._previous.keep(n, offsets, *buffers)
        return MeshBasis(offsets[: n + 1], *(b[:used] for b in buffers))

    def projector(self):
        """Return the particle → Q1 projection (:class:`mpm.mesh_projection.MeshProjector`)."""
        from mpm.mesh_projection import MeshProjector

        return MeshProjector(self.corners, self.coords)


def _weight_buffers(size: int) -> tuple[np.ndarray, ...]:
    """Offsets and entries (nodes, weights, gradients, offsets from the particle) of the weights."""
    return (np.empty(1, dtype=np.int64), np.empty(size, np.int64), np.empty(size),
            np.empty((size, 2)), np.empty((size, 2)))


class MeshBasis:
    """Domain weights at the particles (:func:`mpm.mesh_weights.domain_basis`), kernel input.

    Attributes:
        arrays: ``(offsets, nodes, S, ∇S, x_i - x_p)``, the kernels' basis argument: per
            entry the node, its weight, its weight's gradient and its offset from the particle.
    """

    def __init__(self, *arrays: np.ndarray) -> None:
        self.arrays = arrays
