"""The :class:`~fem_runout.mesh.Discretization` of an unstructured quadrilateral mesh (issue 17).

A gmsh mesh of an outline (:mod:`fem_runout.meshing`) or a user's ``.msh`` file has no grid:
the arrays every method shares are built from the DOLFINx mesh itself, and every quantity
that the rectangle gets from its grid formula is made partition-independent another way:

- node coordinates from the mesh geometry (input bits, the same on every rank);
- exact nodal sums: the slot of a cell at a node is the rank of the cell's *input* index
  (``topology.original_cell_index``) among the node's cells, settled by the node's owner, so
  :meth:`~fem_runout.mesh.Discretization.cell_sum` adds the same numbers in the same order on
  any partition;
- boundary sides from the facet tags: per node ``∫ φ_i n ds`` over the open and the wall
  facets (two facets per boundary node: their sum is the same bits in either order);
- the cell–edge data of TG2-PC's corrector (:class:`Edges`, :mod:`fem_runout.tg2.edges`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem, la, mesh
from mpi4py import MPI

from fem_runout.mesh import (
    Discretization,
    Side,
    cell_integrals,
    node_coordinates,
    rectangle_facets,
)

__all__ = ["EDGE_CORNERS", "Edges", "cell_slots", "discretization_from_mesh",
           "gmsh_discretization", "rectangle_edges"]

#: Local corners of the four edges of a DOLFINx quadrilateral (basix reference order).
EDGE_CORNERS = np.array([[0, 1], [0, 2], [1, 3], [2, 3]], dtype=np.int64)
#: Wall nodes whose two facets' normals differ by more than 45° are corners.
_CORNER_COS = float(np.cos(np.radians(22.5)))
KIND_CODES = {"open": 1, "wall": 2}


@dataclass(frozen=True)
class Edges:
    """Per local cell and local edge: what TG2-PC's edge integrals need.

    Attributes:
        neighbour: (n_cells, 4) local cell across the edge, -1 on the boundary.
        kind: (n_cells, 4) 0 interior, 1 open boundary, 2 wall.
        normal: (n_cells, 4, 2) outward unit normal.
        length: (n_cells, 4) edge length.
        depth: (n_cells, 4) ``2 (x_e - x_K)·n``: the distance to the mirrored cell centre.
        corner_edges: (n_cells, 4, 2) the two edges at each corner, in a fixed geometric order
            (edge midpoints sorted by x, then y): the order of the corrector's sums.
        grad_centre: (n_cells, 4, 2) ``∫_K ∇φ_a = Σ_{e ∋ a} |e|/2 n_e`` (the same as the UFL
            corrector's one-point rule ``∇φ_a |det J|`` at the centre, exact on any
            quadrilateral: the integrand is bilinear in the reference coordinates).
        mean_weight: (n_cells, 4) ``∫_K φ_a / |K|``: the DG0 projection of a Q1 field.
    """

    neighbour: np.ndarray
    kind: np.ndarray
    normal: np.ndarray
    length: np.ndarray
    depth: np.ndarray
    corner_edges: np.ndarray
    grad_centre: np.ndarray
    mean_weight: np.ndarray


def gmsh_discretization(case, comm: MPI.Comm) -> Discretization:
    """Mesh ``domain.outline`` / ``domain.mesh`` with gmsh on rank 0 and distribute it.

    Facets in the physical groups ``open`` and ``wall`` get that kind; other boundary facets
    get ``domain.boundary``'s (collective).
    """
    from dolfinx.io import gmsh as gmshio

    from fem_runout.errors import CaseError
    from fem_runout.meshing import build_model, gmsh_session
    from fem_runout.parallel import agree_on_errors

    partitioner = mesh.create_cell_partitioner(mesh.GhostMode.shared_facet, 2)

    def on_root():
        if comm.rank != 0:
            return None
        session = gmsh_session()
        session.__enter__()
        try:
            build_model(case)
        except BaseException:
            session.__exit__(None, None, None)
            raise
        return session

    session = agree_on_errors(comm, on_root)
    try:
        import gmsh

        model = gmsh.model if comm.rank == 0 else None
        data = gmshio.model_to_mesh(model, comm, 0, gdim=2, partitioner=partitioner)
    finally:
        if session is not None:
            session.__exit__(None, None, None)
    msh = data.mesh
    if msh.topology.cell_type != mesh.CellType.quadrilateral:
        raise CaseError("domain: the mesh must be made of quadrilaterals")
    fdim = msh.topology.dim - 1
    msh.topology.create_entities(fdim)
    fmap = msh.topology.index_map(fdim)
    facet_kind = np.zeros(fmap.size_local + fmap.num_ghosts, dtype=np.int64)
    tags = data.facet_tags
    for name, code in KIND_CODES.items():
        group = data.physical_groups.get(name)
        if tags is not None and group is not None and group[0] == fdim:
            facet_kind[tags.find(group[1])] = code
    default = case.domain.default_boundary
    return discretization_from_mesh(comm, msh, facet_kind, default)


def discretization_from_mesh(comm: MPI.Comm, msh: mesh.Mesh, facet_kind: np.ndarray,
                             default_kind: str = "open") -> Discretization:
    """Build the discretization of a quadrilateral DOLFINx mesh (collective).

    Args:
        comm: Communicator of the mesh.
        msh: The mesh (ghost mode ``shared_facet``).
        facet_kind: (n_facets_local,) int: 1 open, 2 wall, 0 untagged (``default_kind``) on
            the boundary; ignored on interior facets.
        default_kind: Kind of untagged boundary facets.
    """
    V = fem.functionspace(msh, ("Lagrange", 1))
    tdim = msh.topology.dim
    cmap, imap = msh.topology.index_map(tdim), V.dofmap.index_map
    n_cells = cmap.size_local + cmap.num_ghosts
    cell_nodes = np.asarray(V.dofmap.list[:n_cells], dtype=np.int64)
    coords = node_coordinates(V)[:, :2].copy()
    C, phi_int, area = cell_integrals(coords[cell_nodes])
    if np.any(area <= 0.0):
        raise ValueError("the mesh has cells of zero area")
    slot, n_slots = cell_slots(comm, imap, cell_nodes[: cmap.size_local],
                               np.asarray(msh.topology.original_cell_index[: cmap.size_local]))
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    if coords.size:
        lo, hi = coords.min(axis=0), coords.max(axis=0)
    lo, hi = np.ascontiguousarray(lo, float), np.ascontiguousarray(hi, float)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    disc = Discretization(
        comm=comm, mesh=msh, V=V, extent=(float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])),
        cells=(comm.allreduce(cmap.size_local), 0), n_owned_nodes=imap.size_local,
        n_owned_cells=cmap.size_local, cell_nodes=cell_nodes, C=C, cell_area=area,
        lumped_mass=np.empty(0), coords=coords, sides=[],
        slot=np.vstack([slot, np.zeros((n_cells - slot.shape[0], 4), np.int64)]),
        n_slots=n_slots, structured=False,
    )
    disc.lumped_mass = disc.cell_sum(phi_int[: cmap.size_local])
    kinds = _facet_kinds(msh, facet_kind, default_kind)
    disc.edges = _edges(msh, coords, cell_nodes, kinds, phi_int / area[:, None])
    disc.min_cell_size = comm.allreduce(float(disc.edges.length.min()) if n_cells else np.inf,
                                        op=MPI.MIN)
    disc.sides = _sides(disc, disc.edges)
    return disc


def rectangle_edges(disc: Discretization) -> Edges:
    """Return the :class:`Edges` of the structured rectangle (TG2-PC's cell-by-cell corrector).

    A boundary facet takes the kind of its side (``disc.sides``); the node coordinates are the
    grid formula's, so every array is the same bits on any partition. ``mean_weight`` is the
    exact ¼ of a rectangle.
    """
    facets, _, on = rectangle_facets(disc)
    kinds = np.zeros(facets.size, dtype=np.int64)
    for side in disc.sides:
        kinds[on[side.name]] = KIND_CODES[side.kind]
    weight = np.full(disc.cell_nodes.shape, 0.25)
    return _edges(disc.mesh, disc.coords, disc.cell_nodes, kinds, weight)


def cell_slots(comm: MPI.Comm, imap, cell_nodes: np.ndarray,
               keys: np.ndarray) -> tuple[np.ndarray, int]:
    """Slot of every owned cell at each of its nodes: the rank of its key among the node's cells.

    The owner of each node gathers ``(node, cell key)`` from every rank, sorts the keys and
    sends each cell its position (collective).

    Args:
        comm: Communicator.
        imap: Index map of the Q1 dofs.
        cell_nodes: (n_owned_cells, 4) local nodes of the owned cells.
        keys: (n_owned_cells,) partition-independent cell keys (input indices).

    Returns:
        (n_owned_cells, 4) slots and the number of slots (the most cells at a node, global).
    """
    flat = cell_nodes.ravel()
    glob = np.asarray(imap.local_to_global(flat.astype(np.int32)), dtype=np.int64)
    n_own = imap.size_local
    owners = np.full(flat.size, comm.rank, dtype=np.int64)
    ghost = flat >= n_own
    owners[ghost] = np.asarray(imap.owners)[flat[ghost] - n_own]
    key = np.repeat(np.asarray(keys, dtype=np.int64), 4)
    order = np.argsort(owners, kind="stable")
    counts = np.bincount(owners, minlength=comm.size)
    sent = np.stack([glob[order], key[order]], axis=1)
    parts = comm.alltoall(np.split(sent, np.cumsum(counts)[:-1]))
    got = np.concatenate(parts) if parts else np.empty((0, 2), np.int64)
    slot_got = np.empty(got.shape[0], dtype=np.int64)
    if got.shape[0]:
        by = np.lexsort((got[:, 1], got[:, 0]))
        node = got[by, 0]
        start = np.flatnonzero(np.r_[True, node[1:] != node[:-1]])
        first = np.repeat(start, np.diff(np.r_[start, node.size]))
        slot_got[by] = np.arange(node.size) - first
    sizes = [p.shape[0] for p in parts]
    back = comm.alltoall(np.split(slot_got, np.cumsum(sizes)[:-1]))
    slot = np.empty(flat.size, dtype=np.int64)
    slot[order] = np.concatenate(back) if back else np.empty(0, np.int64)
    local_max = int(slot.max()) + 1 if slot.size else 0
    return slot.reshape(-1, 4), comm.allreduce(local_max, op=MPI.MAX)


def _facet_kinds(msh: mesh.Mesh, facet_kind: np.ndarray, default_kind: str) -> np.ndarray:
    """Kind code of every local facet: 0 interior, 1 open, 2 wall (global boundary only)."""
    fdim = msh.topology.dim - 1
    msh.topology.create_entities(fdim)
    msh.topology.create_connectivity(fdim, fdim + 1)
    fmap = msh.topology.index_map(fdim)
    n = fmap.size_local + fmap.num_ghosts
    out = np.zeros(n, dtype=np.int64)
    boundary = mesh.exterior_facet_indices(msh.topology)
    given = np.asarray(facet_kind, dtype=np.int64)[boundary]
    out[boundary] = np.where(given > 0, given, KIND_CODES[default_kind])
    return out


def _edges(msh: mesh.Mesh, coords: np.ndarray, cell_nodes: np.ndarray,
           kinds: np.ndarray, mean_weight: np.ndarray) -> Edges:
    """Return the cell–edge arrays of :class:`Edges` for every local cell."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, tdim - 1)
    msh.topology.create_connectivity(tdim - 1, tdim)
    c2f, f2c = msh.topology.connectivity(tdim, tdim - 1), msh.topology.connectivity(tdim - 1, tdim)
    n = cell_nodes.shape[0]
    facets = np.asarray(c2f.array, dtype=np.int64).reshape(-1, 4)[:n]
    offsets, links = np.asarray(f2c.offsets), np.asarray(f2c.array, dtype=np.int64)
    first, count = links[offsets[facets]], offsets[facets + 1] - offsets[facets]
    second = np.where(count > 1, links[np.minimum(offsets[facets] + 1, links.size - 1)], -1)
    cells = np.arange(n)[:, None]
    neighbour = np.where(first == cells, second, first)
    kind = kinds[facets]
    neighbour[kind > 0] = -1
    xc = coords[cell_nodes]
    p, q = xc[:, EDGE_CORNERS[:, 0]], xc[:, EDGE_CORNERS[:, 1]]
    t = q - p
    length = np.hypot(t[..., 0], t[..., 1])
    normal = np.stack([t[..., 1], -t[..., 0]], axis=-1) / length[..., None]
    mid = 0.5 * (p + q)
    out = np.einsum("kea,kea->ke", mid - xc.mean(axis=1)[:, None], normal)
    normal *= np.where(out < 0.0, -1.0, 1.0)[..., None]
    depth = 2.0 * np.abs(out)
    corner_edges = np.empty((n, 4, 2), dtype=np.int64)
    for a in range(4):
        pair = np.flatnonzero((EDGE_CORNERS == a).any(axis=1))
        m0, m1 = mid[:, pair[0]], mid[:, pair[1]]
        swap = (m1[:, 0] < m0[:, 0]) | ((m1[:, 0] == m0[:, 0]) & (m1[:, 1] < m0[:, 1]))
        corner_edges[:, a, 0] = np.where(swap, pair[1], pair[0])
        corner_edges[:, a, 1] = np.where(swap, pair[0], pair[1])
    grad = np.zeros((n, 4, 2))  # ∫_K ∇φ_a = ∮ φ_a n ds = Σ_{e ∋ a} |e|/2 n_e (exact)
    for e, (a, b) in enumerate(EDGE_CORNERS):
        half = 0.5 * length[:, e, None] * normal[:, e]
        grad[:, a] += half
        grad[:, b] += half
    return Edges(neighbour, kind, normal, length, depth, corner_edges, grad, mean_weight)


def _sides(disc: Discretization, edges: Edges) -> list[Side]:
    """Return the open and the wall side: per node ``∫ φ_i n ds`` and ``∫ φ_i ds`` of their facets.

    Each boundary facet is counted by its owned cell; the nodal sums go to the owners (two
    facets per boundary node: the same bits in either order) and back to the ghosts.
    """
    n_own = disc.n_owned_cells
    nn = disc.coords.shape[0]
    out = []
    for name, code in KIND_CODES.items():
        acc = np.zeros((nn, 3))
        k, e = np.nonzero(edges.kind[:n_own] == code)
        for c in range(2):
            node = disc.cell_nodes[k, EDGE_CORNERS[e, c]]
            half = 0.5 * edges.length[k, e]
            np.add.at(acc, node, np.column_stack([half[:, None] * edges.normal[k, e], half]))
        if disc.comm.size > 1:
            vec = la.vector(disc.V.dofmap.index_map, 3)
            vec.array[:] = acc.ravel()
            vec.scatter_reverse(la.InsertMode.add)
            vec.scatter_forward()
            acc = vec.array.reshape(nn, 3).copy()
        nodes = np.flatnonzero(acc[:, 2] > 0.0)
        vec_n = acc[nodes, :2]
        weight = np.hypot(vec_n[:, 0], vec_n[:, 1])
        normal = vec_n / np.where(weight > 0.0, weight, 1.0)[:, None]
        corner = weight < _CORNER_COS * acc[nodes, 2] if name == "wall" else None
        out.append(Side(name, name, normal, nodes, weight, corner))
    return out
