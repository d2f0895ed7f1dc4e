"""Structured quadrilateral mesh, the Q1/DG0/DQ1 spaces and the per-cell geometric arrays.

Every method shares one :class:`Discretization`: the Q1 space holds the state, the lumped Q1
mass is the nodal area, and the cell–node arrays (``cell_nodes``, ``C``) feed the vectorised
kernels (low-order fluxes, FCT, particle transfers).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import basix
import numpy as np
from dolfinx import fem, la, mesh
from mpi4py import MPI

from fem_runout import cellsum
from fem_runout.q1 import inverses, jacobians, physical_gradients, q1_basis
from fem_runout.shared_nodes import SharedRows, sharing_ranks

SIDES = ("left", "right", "bottom", "top")
SIDE_NORMALS = {"left": (-1.0, 0.0), "right": (1.0, 0.0), "bottom": (0.0, -1.0), "top": (0.0, 1.0)}


@dataclass
class Side:
    """A part of the boundary with one kind: a side of the rectangle, or all open/wall facets.

    Attributes:
        name: left, right, bottom or top (rectangle); open or wall (unstructured mesh).
        kind: ``"open"`` or ``"wall"``.
        normal: (n, 2) outward unit normal per node: the direction of ``∫ φ_i n ds``.
        nodes: Local node indices on the side.
        weight: ``|∫_side φ_i n ds|`` for those nodes (``∫ φ_i ds`` on a straight side).
        corner: (n,) bool, wall nodes where the wall turns by more than 45°: both momentum
            components are zeroed there (None: no corner).
    """

    name: str
    kind: str
    normal: np.ndarray
    nodes: np.ndarray
    weight: np.ndarray
    corner: np.ndarray | None = None

    def take(self, ok: np.ndarray, nodes: np.ndarray) -> Side:
        """Return the side restricted to the rows ``ok``, with node indices ``nodes``."""
        corner = None if self.corner is None else self.corner[ok]
        return Side(self.name, self.kind, self.normal[ok], nodes, self.weight[ok], corner)


def zero_wall_normal(sides, mx: np.ndarray, my: np.ndarray) -> None:
    """Zero the wall-normal component of a nodal vector (mx, my) on the wall sides, in place.

    ``m ← m - (m·n) n`` with the node's normal (on an axis-aligned wall that zeroes one
    component exactly; a corner node of two walls loses both). ``mx``, ``my`` may be column
    views.
    """
    for side in sides:
        if side.kind != "wall":
            continue
        i, n = side.nodes, side.normal
        mn = mx[i] * n[:, 0] + my[i] * n[:, 1]
        mx[i] -= mn * n[:, 0]
        my[i] -= mn * n[:, 1]
        if side.corner is not None:
            mx[i[side.corner]] = 0.0
            my[i[side.corner]] = 0.0


@dataclass
class Discretization:
    """Mesh, spaces and precomputed arrays of a structured run.

    Attributes:
        comm: Communicator.
        mesh: The quadrilateral mesh.
        V: Scalar Q1 space (the state space).
        extent: (xmin, xmax, ymin, ymax).
        cells: (nx, ny) number of cells.
        n_owned_nodes: Owned Q1 dofs on this rank.
        n_owned_cells: Owned cells on this rank.
        cell_nodes: (n_cells_local, 4) local Q1 dofs of every local cell (owned, then ghosts).
        C: (n_cells_local, 4, 4, 2) array ``∫_K φ_i ∇φ_j``.
        cell_area: (n_cells_local,) cell areas.
        lumped_mass: Nodal areas ``∫ φ_i`` for local nodes (owned then ghosts).
        coords: (n_nodes_local, 2) node coordinates.
        sides: Boundary sides with their kind, nodes and weights.
        slot: (n_cells_local, 4) slot of every cell node in the exact nodal sums.
        n_slots: Slots per node: 4 on the rectangle, the most cells around a node otherwise.
        structured: True for the rectangle's uniform grid (``extent``, ``cells`` and
            ``spacing`` describe it); False for an unstructured mesh (``extent`` is the
            bounding box, ``cells`` is ``(n_cells, 0)``).
        min_cell_size: Shortest cell edge over the mesh [m].
        edges: The unstructured mesh's cell–edge data (:class:`fem_runout.quadmesh.Edges`),
            None on the rectangle.
    """

    comm: MPI.Comm
    mesh: mesh.Mesh
    V: fem.FunctionSpace
    extent: tuple[float, float, float, float]
    cells: tuple[int, int]
    n_owned_nodes: int
    n_owned_cells: int
    cell_nodes: np.ndarray
    C: np.ndarray
    cell_area: np.ndarray
    lumped_mass: np.ndarray
    coords: np.ndarray
    sides: list[Side]
    slot: np.ndarray | None = None
    n_slots: int = 4
    structured: bool = True
    min_cell_size: float = 0.0
    edges: object | None = None

    @property
    def spacing(self) -> tuple[float, float]:
        """Cell size (dx, dy) of the structured grid."""
        if not self.structured:
            raise AttributeError("an unstructured mesh has no grid spacing (use min_cell_size)")
        xmin, xmax, ymin, ymax = self.extent
        return (xmax - xmin) / self.cells[0], (ymax - ymin) / self.cells[1]

    def cell_sum(self, contrib: np.ndarray) -> np.ndarray:
        """``Σ_K contrib[K, a]`` per node over the owned cells, the same bits on any partition.

        Args:
            contrib: (n_owned_cells, 4) or (n_owned_cells, 4, bs) per cell and node.

        Returns:
            (n_nodes_local,) or (n_nodes_local, bs), owned and ghost entries filled
            (:mod:`fem_runout.cellsum`).
        """
        n = self.n_owned_cells
        bs = 1 if contrib.ndim == 2 else contrib.shape[2]
        nn = self.coords.shape[0]
        src = self.__dict__.get("_src")
        if src is None:
            src = self.__dict__["_src"] = cellsum.sources(self.cell_nodes[:n], self.slot[:n], nn,
                                                          self.n_slots)
        flat = np.ascontiguousarray(contrib.reshape(n * 4, bs))
        out = np.empty((nn, bs))
        if self.comm.size == 1:
            cellsum.gather_total(src, flat, out)
        else:
            vec = self._vector(self.n_slots * bs)
            buf = vec.array.reshape(nn, self.n_slots, bs)
            every = self.__dict__.setdefault("_every_node", np.arange(nn))
            cellsum.gather_on(src, flat, every, buf)
            vec.scatter_reverse(la.InsertMode.add)  # each slot has one non-zero: exact
            vec.scatter_forward()
            cellsum.total_on(buf, every, out)
        return out[:, 0] if contrib.ndim == 2 else out

    def update_ghosts(self, values: np.ndarray) -> None:
        """Copy owned values to the ghost entries of ``values`` (in place)."""
        if self.comm.size == 1:
            return
        bs = 1 if values.ndim == 1 else values.shape[1]
        vec = self._vector(bs)
        vec.array[:] = values.reshape(-1)
        vec.scatter_forward()
        values.reshape(-1)[:] = vec.array

    def _vector(self, bs: int) -> la.Vector:
        cache = self.__dict__.setdefault("_vectors", {})
        if bs not in cache:
            cache[bs] = la.vector(self.V.dofmap.index_map, bs)
        return cache[bs]


def build_discretization(
    comm: MPI.Comm,
    extent: tuple[float, float, float, float],
    cells: tuple[int, int],
    boundary: dict[str, str],
    partitioner: Callable | None = None,
) -> Discretization:
    """Create the mesh, the Q1 space and every geometric array.

    Args:
        comm: Communicator.
        extent: (xmin, xmax, ymin, ymax).
        cells: (nx, ny).
        boundary: Kind (``"open"``/``"wall"``) of each side.
        partitioner: A DOLFINx cell partitioner (:mod:`fem_runout.partition`), or None for
            DOLFINx's graph partitioner.

    Returns:
        The discretization.
    """
    xmin, xmax, ymin, ymax = extent
    msh = mesh.create_rectangle(
        comm, [[xmin, ymin], [xmax, ymax]], list(cells), mesh.CellType.quadrilateral,
        ghost_mode=mesh.GhostMode.shared_facet, partitioner=partitioner,
    )
    V = fem.functionspace(msh, ("Lagrange", 1))
    tdim = msh.topology.dim
    cmap = msh.topology.index_map(tdim)
    n_cells = cmap.size_local + cmap.num_ghosts
    cell_nodes = np.asarray(V.dofmap.list[:n_cells], dtype=np.int64)
    coords = V.tabulate_dof_coordinates()[:, :2].copy()
    # snapped to the grid formula: tabulated coordinates are pushed forward from whichever
    # cell a rank holds and differ in the last bit between partitions
    for axis, (lo, n) in enumerate(((xmin, cells[0]), (ymin, cells[1]))):
        step = ((xmax - xmin) if axis == 0 else (ymax - ymin)) / n
        coords[:, axis] = lo + np.rint((coords[:, axis] - lo) / step) * step
    C, phi_int, area = cell_integrals(coords[cell_nodes])
    disc = Discretization(
        comm=comm, mesh=msh, V=V, extent=tuple(map(float, extent)), cells=tuple(cells),
        n_owned_nodes=V.dofmap.index_map.size_local, n_owned_cells=cmap.size_local,
        cell_nodes=cell_nodes, C=C, cell_area=area, lumped_mass=np.empty(0), coords=coords,
        sides=[], min_cell_size=float(min((xmax - xmin) / cells[0], (ymax - ymin) / cells[1])),
    )
    disc.slot = cellsum.cell_slots(coords[cell_nodes])
    disc.lumped_mass = disc.cell_sum(phi_int[: cmap.size_local])
    disc.sides = [_side(disc, name, boundary.get(name, "open")) for name in SIDES]
    return disc


def physical_basis(xc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q1 basis, its physical gradients and the weights at the Gauss points of bilinear cells.

    Args:
        xc: (n_cells, 4, 2) node coordinates in the Q1 reference order.

    Returns:
        ``(phi, grad, w)``: (nq, 4) values, (n_cells, nq, 4, 2) gradients and (n_cells, nq)
        weights ``w_q |det J|`` (basix's degree-4 rule).
    """
    pts, wts = basix.make_quadrature(basix.CellType.quadrilateral, 4)
    phi, dphi = q1_basis(pts)  # closed form: basix's tabulation depends on the CPU's BLAS
    Jinv, detJ = inverses(jacobians(xc, dphi))  # of dx_a / dX_b
    grad = physical_gradients(dphi, Jinv)
    return phi, grad, wts[None, :] * np.abs(detJ)


def cell_integrals(xc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``∫_K φ_i ∇φ_j``, ``∫_K φ_i`` and |K| for bilinear cells with node coordinates ``xc``.

    Args:
        xc: (n_cells, 4, 2) node coordinates in the Q1 reference order.
    """
    phi, grad, w = physical_basis(xc)
    C = np.einsum("cq,qi,cqja->cija", w, phi, grad)
    phi_int = np.einsum("cq,qi->ci", w, phi)
    return C, phi_int, w.sum(axis=1)


def element_masses(cells: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """(n_cells, 4, 4) element mass matrices ``∫_K φ_a φ_b`` of bilinear quadrilaterals.

    ``cells`` (n_cells, 4) in basix's Q1 order, ``coords`` (n_nodes, 2); the Gauss rule is
    exact for a bilinear map (``det J`` affine). The matrices are exactly symmetric.
    """
    pts, wts = basix.make_quadrature(basix.CellType.quadrilateral, 4)
    phi, dphi = q1_basis(pts)
    jac = jacobians(coords[cells], dphi)
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    mass = np.einsum("cq,qi,qj->cij", wts[None, :] * np.abs(det), phi, phi)
    return 0.5 * (mass + mass.transpose(0, 2, 1))


def _side(disc: Discretization, name: str, kind: str) -> Side:
    """Nodes of one side and their boundary weights ``∫ φ_i ds`` (exact for Q1)."""
    xmin, xmax, ymin, ymax = disc.extent
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    axis, value = {"left": (0, xmin), "right": (0, xmax), "bottom": (1, ymin), "top": (1, ymax)}[
        name
    ]
    nodes = np.flatnonzero(np.abs(disc.coords[:, axis] - value) < tol)
    along = (y if axis == 0 else x)[nodes]
    lo, hi = (ymin, ymax) if axis == 0 else (xmin, xmax)
    n_cells = disc.cells[1] if axis == 0 else disc.cells[0]
    h = (hi - lo) / n_cells
    weight = np.where((np.abs(along - lo) < tol) | (np.abs(along - hi) < tol), 0.5 * h, h)
    return Side(name, kind, np.tile(SIDE_NORMALS[name], (nodes.size, 1)), nodes, weight)


class GhostReducer:
    """Max/min reduction of nodal values over the ranks that share a node.

    dolfinx scatters only add or insert; the FCT bounds need the extremum over a node's whole
    patch, which straddles ranks. Every rank sends its values at its shared nodes to the other
    ranks holding them and reduces what it receives (exact: max and min; one message).
    :meth:`on` gives the exchanges of arrays that hold a subset of the local nodes (the active
    set's).
    """

    def __init__(self, disc: Discretization) -> None:
        imap = disc.V.dofmap.index_map
        self.disc = disc
        self.comm = disc.comm
        self.shared, self.counts = sharing_ranks(
            self.comm, imap.size_local, np.asarray(imap.ghosts), np.asarray(imap.owners),
            int(imap.local_range[0]))
        self._all = SharedRows(self.comm, self.shared, self.counts)

    def reduce(self, values: np.ndarray, op: str) -> None:
        """Reduce ``values`` in place with ``op`` = "max" or "min" over the sharing ranks.

        Args:
            values: (n,) local values (owned then ghosts), or (k, n): k arrays reduced
                together (one exchange).
            op: "max" or "min".
        """
        self._all.reduce(values, op)

    def on(self, nodes: np.ndarray) -> SharedRows:
        """Return the exchanges of compact arrays ``a``, ``a[k]`` the value at ``nodes[k]``.

        Every rank must hold the same set of shared nodes (as the active set's nodes are);
        only the set's shared nodes are sent (:mod:`fem_runout.shared_nodes`).
        """
        inv = np.full(self.disc.coords.shape[0], -1, dtype=np.int64)
        inv[nodes] = np.arange(nodes.size)
        rows = inv[self.shared]
        keep = rows >= 0
        ranks = np.repeat(np.arange(self.comm.size), self.counts)[keep]
        return SharedRows(self.comm, rows[keep], np.bincount(ranks, minlength=self.comm.size))


def rectangle_facets(disc: Discretization) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Return the rectangle's local facets (owned and ghosts), midpoints and sides' facets.

    Returns:
        ``(facets, midpoints, on)``: ``on[name]`` is the bool mask of the facets on side
        ``name`` (left, right, bottom, top).
    """
    msh = disc.mesh
    fdim = msh.topology.dim - 1
    msh.topology.create_entities(fdim)
    msh.topology.create_connectivity(fdim, fdim + 1)
    fmap = msh.topology.index_map(fdim)
    facets = np.arange(fmap.size_local + fmap.num_ghosts, dtype=np.int32)
    mid = mesh.compute_midpoints(msh, fdim, facets)
    xmin, xmax, ymin, ymax = disc.extent
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    where = {"left": (0, xmin), "right": (0, xmax), "bottom": (1, ymin), "top": (1, ymax)}
    return facets, mid, {name: np.abs(mid[:, axis] - value) < tol
                         for name, (axis, value) in where.items()}


def node_coordinates(V: fem.FunctionSpace) -> np.ndarray:
    """Coordinates of the local nodes (owned, then ghosts) of a degree-1 Lagrange space.

    Taken from the mesh geometry, so they are the mesh's own numbers, bit for bit.
    ``tabulate_dof_coordinates`` pushes the reference points forward through each cell's
    map instead, which leaves a last-bit error that depends on the cell a rank holds and on
    the CPU's floating-point kernels (x = 50 came out as 50.000000000000007 on an AVX-512
    machine, and below 50 on the one where the tests were written).

    Args:
        V: A Q1 space (scalar or blocked) on a mesh with Q1 geometry.

    Returns:
        (n_local, 3) coordinates; row ``i`` belongs to local node ``i``.
    """
    msh = V.mesh
    tdim = msh.topology.dim
    cells = msh.topology.index_map(tdim)
    n_cells = cells.size_local + cells.num_ghosts
    dofs = np.asarray(V.dofmap.list[:n_cells])
    geo = np.asarray(msh.geometry.dofmaps[0][:n_cells])
    if dofs.shape != geo.shape:
        raise ValueError("node_coordinates needs the mesh's own degree (Q1 on Q1 geometry)")
    imap = V.dofmap.index_map
    out = np.empty((imap.size_local + imap.num_ghosts, 3))
    out[dofs.ravel()] = msh.geometry.x[geo.ravel()]
    return out
