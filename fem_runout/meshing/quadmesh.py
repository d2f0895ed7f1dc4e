"""Quadrilateral meshes as arrays: checks, boundary groups, quality, and the gmsh model.

Every mesh a case gives (rectangle, outline, ``.msh`` file) ends as a :class:`QuadMesh`:
first-order quadrilaterals, counterclockwise, convex, and boundary edges sorted into the
groups ``open`` and ``wall`` (each boundary edge exactly once). :func:`to_gmsh` writes it as
a clean discrete gmsh model (nodes numbered 1..N, one 2D physical group ``domain``, 1D groups
``open`` and ``wall``) that ``dolfinx.io.gmsh.model_to_mesh`` reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fem_runout.errors import CaseError

__all__ = [
    "BOUNDARY_TAGS",
    "DOMAIN_TAG",
    "GROUPS",
    "QuadMesh",
    "corner_sines",
    "finish_mesh",
    "mesh_quality",
    "quad_areas",
    "read_model",
    "to_gmsh",
]

GROUPS: tuple[str, ...] = ("open", "wall")
DOMAIN_TAG = 1  # physical tag (dim 2) of the group "domain"
BOUNDARY_TAGS: dict[str, int] = {"open": 1, "wall": 2}  # physical tags (dim 1)
_MIN_SINE = 1e-6  # a corner whose sine is below this is degenerate


@dataclass(frozen=True, eq=False)
class QuadMesh:
    """A checked quadrilateral mesh.

    Attributes:
        nodes: ``(N, 2)`` node coordinates [m], every node used by a quadrilateral.
        quads: ``(M, 4)`` node indices (0-based), counterclockwise, convex.
        groups: ``open``/``wall`` -> ``(K, 2)`` boundary edges (node indices), directed so
            that the domain is on their left; together every boundary edge exactly once.
    """

    nodes: np.ndarray
    quads: np.ndarray
    groups: dict[str, np.ndarray]

    def boundary_nodes(self) -> np.ndarray:
        """Sorted indices of the nodes on the boundary (those of the groups' edges)."""
        return np.unique(np.concatenate([np.asarray(e, dtype=np.int64).ravel()
                                         for e in self.groups.values()]))


def corner_sines(points: np.ndarray) -> np.ndarray:
    """``sin`` of every corner angle of ``(M, 4, 2)`` quads, signed (> 0: counterclockwise)."""
    a = np.roll(points, -1, axis=1) - points
    b = np.roll(points, 1, axis=1) - points
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    norm = np.linalg.norm(a, axis=2) * np.linalg.norm(b, axis=2)
    return cross / np.where(norm > 0, norm, 1.0) * (norm > 0)


def quad_areas(nodes: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Signed areas of ``(M, 4)`` quadrilaterals (positive counterclockwise)."""
    p = np.asarray(nodes)[np.asarray(quads)]
    x, y = p[..., 0], p[..., 1]
    return 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)


def _orient(nodes: np.ndarray, quads: np.ndarray, key: str) -> np.ndarray:
    """Make every quad counterclockwise; refuse non-convex or degenerate ones."""
    sines = corner_sines(nodes[quads])
    clockwise = (sines < -_MIN_SINE).all(axis=1)
    quads = np.where(clockwise[:, None], quads[:, [0, 3, 2, 1]], quads)
    bad = ~(clockwise | (sines > _MIN_SINE).all(axis=1))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        x, y = nodes[quads[i]].mean(axis=0)
        raise CaseError(f"{key}: {int(bad.sum())} of {len(quads)} quadrilaterals are not convex "
                        f"or are degenerate (e.g. cell {i} at x={x:.6g}, y={y:.6g}); "
                        "allowed: convex quadrilaterals with corner angles in (0, 180) deg")
    return quads


def _edge_keys(edges: np.ndarray, n: int) -> np.ndarray:
    return edges.min(axis=1).astype(np.int64) * n + edges.max(axis=1)


def _boundary(nodes: np.ndarray, quads: np.ndarray, key: str) -> np.ndarray:
    """Directed boundary edges (domain on the left); refuse edges shared by > 2 cells."""
    edges = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    _, inverse, counts = np.unique(_edge_keys(edges, len(nodes)), return_inverse=True,
                                   return_counts=True)
    if (counts > 2).any():
        e = edges[np.flatnonzero(counts[inverse] > 2)[0]]
        x, y = nodes[e].mean(axis=0)
        raise CaseError(f"{key}: {int((counts > 2).sum())} edges are shared by more than two "
                        f"quadrilaterals (e.g. at x={x:.6g}, y={y:.6g}); the mesh must be a "
                        "conforming surface")
    return edges[counts[inverse] == 1]


def _where(nodes: np.ndarray, edge: np.ndarray) -> str:
    (x0, y0), (x1, y1) = nodes[edge]
    return f"({x0:.6g}, {y0:.6g})-({x1:.6g}, {y1:.6g})"


def _group(nodes: np.ndarray, bnd: np.ndarray, tagged: Mapping[str, np.ndarray],
           key: str) -> np.ndarray:
    """Group index (into GROUPS, -1 untagged) of every boundary edge ``bnd``."""
    bkeys = _edge_keys(bnd, len(nodes))
    out = np.full(len(bkeys), -1)
    for g, name in enumerate(GROUPS):
        edges = tagged.get(name, np.empty((0, 2), np.int64))
        tkeys = _edge_keys(edges, len(nodes)) if len(edges) else np.empty(0, np.int64)
        inside = np.isin(tkeys, bkeys)
        if not inside.all():
            e = edges[np.flatnonzero(~inside)[0]]
            raise CaseError(f"{key}: physical group '{name}' holds {int((~inside).sum())} edges "
                            f"that are not boundary edges of the quadrilaterals (e.g. "
                            f"{_where(nodes, e)}); allowed: boundary edges only")
        hit = np.isin(bkeys, tkeys)
        if (hit & (out >= 0)).any():
            e = bnd[np.flatnonzero(hit & (out >= 0))[0]]
            raise CaseError(f"{key}: {int((hit & (out >= 0)).sum())} boundary edges are in both "
                            f"groups open and wall (e.g. {_where(nodes, e)}); allowed: each "
                            "edge in one group")
        out[hit] = g
    return out


def _no_duplicates(nodes: np.ndarray, key: str) -> None:
    """Refuse two nodes at the same place (a crack: the cells on both sides are not joined)."""
    _, first, counts = np.unique(nodes, axis=0, return_index=True, return_counts=True)
    if (counts > 1).any():
        x, y = nodes[first[np.flatnonzero(counts > 1)[0]]]
        raise CaseError(f"{key}: {int((counts > 1).sum())} places hold two or more nodes (e.g. "
                        f"x={x:.6g}, y={y:.6g}): the cells there are not joined; merge "
                        "duplicate nodes (gmsh: Coherence Mesh / removeDuplicateNodes)")


def finish_mesh(nodes: np.ndarray, quads: np.ndarray, tagged: Mapping[str, np.ndarray],
                default: str, key: str) -> QuadMesh:
    """Check a quadrilateral mesh and sort its boundary edges into ``open`` and ``wall``.

    Args:
        nodes: ``(N, 2)`` coordinates (unused nodes are dropped).
        quads: ``(M, 4)`` node indices (0-based), either orientation.
        tagged: ``open``/``wall`` -> ``(K, 2)`` edges given for them (0-based).
        default: Group of the boundary edges in neither (``open`` or ``wall``).
        key: Case key named in errors (``domain.mesh``).

    Raises:
        CaseError: No cells, non-convex or degenerate cells, an edge shared by more than two
            cells, tagged edges off the boundary or in both groups.
    """
    quads = np.asarray(quads, dtype=np.int64)
    if quads.ndim != 2 or quads.shape[1] != 4 or not len(quads):
        raise CaseError(f"{key}: holds no quadrilaterals; allowed: a 2D mesh of quadrilaterals")
    used, inverse = np.unique(quads, return_inverse=True)
    remap = np.full(len(nodes), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    nodes = np.ascontiguousarray(np.asarray(nodes, dtype=np.float64)[used, :2])
    _no_duplicates(nodes, key)
    quads = _orient(nodes, inverse.reshape(quads.shape).astype(np.int64), key)
    ok = {name: remap[np.asarray(e, dtype=np.int64).reshape(-1, 2)] for name, e in tagged.items()}
    for name, e in ok.items():
        if (e < 0).any():
            raise CaseError(f"{key}: physical group '{name}' holds edges whose nodes are not "
                            "nodes of the quadrilaterals; allowed: boundary edges only")
    bnd = _boundary(nodes, quads, key)
    group = _group(nodes, bnd, ok, key)
    group[group < 0] = GROUPS.index(default)
    return QuadMesh(nodes, quads, {name: bnd[group == g] for g, name in enumerate(GROUPS)})


def mesh_quality(nodes: np.ndarray | None = None, quads: np.ndarray | None = None
                 ) -> dict[str, float | int]:
    """Sizes and shape of a quadrilateral mesh (default: the current gmsh model's).

    Args:
        nodes: ``(N, 2)`` coordinates.
        quads: ``(M, 4)`` node indices.

    Returns:
        ``cells``, ``nodes``, ``area`` [m²], ``min_edge``/``mean_edge``/``max_edge`` [m],
        ``min_angle``/``max_angle`` [deg] (corner angles; 90 for squares) and
        ``min_scaled_jacobian`` (smallest sine of a corner angle: 1 for rectangles, <= 0 for
        a non-convex cell).
    """
    if nodes is None or quads is None:
        mesh = read_model()
        nodes, quads = mesh.nodes, mesh.quads
    p = np.asarray(nodes)[np.asarray(quads)][..., :2]
    edge = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
    a, b = np.roll(p, -1, axis=1) - p, np.roll(p, 1, axis=1) - p
    cos = (a * b).sum(axis=2) / (np.linalg.norm(a, axis=2) * np.linalg.norm(b, axis=2))
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    area = quad_areas(nodes, quads)
    return {
        "cells": len(p), "nodes": len(nodes), "area": float(np.abs(area).sum()),
        "min_edge": float(edge.min()), "mean_edge": float(edge.mean()),
        "max_edge": float(edge.max()), "min_angle": float(angle.min()),
        "max_angle": float(angle.max()),
        "min_scaled_jacobian": float(corner_sines(p).min()),
    }


def to_gmsh(mesh: QuadMesh, name: str = "fem_runout") -> None:
    """Write ``mesh`` as a new current gmsh model (gmsh must be initialized).

    Nodes get tags ``1..N`` in the order of ``mesh.nodes``, quadrilaterals ``1..M`` (element
    type 3) on the discrete surface 1 (physical group ``domain``, tag 1), boundary edges
    (type 1) on discrete curves 1 (``open``, tag 1) and 2 (``wall``, tag 2); an empty group
    is left out.
    """
    import gmsh

    gmsh.model.add(name)
    gmsh.model.addDiscreteEntity(2, 1)
    n, m = len(mesh.nodes), len(mesh.quads)
    xyz = np.column_stack([mesh.nodes, np.zeros(n)]).ravel()
    gmsh.model.mesh.addNodes(2, 1, np.arange(1, n + 1), xyz)
    gmsh.model.mesh.addElementsByType(1, 3, np.arange(1, m + 1), (mesh.quads + 1).ravel())
    gmsh.model.addPhysicalGroup(2, [1], DOMAIN_TAG, name="domain")
    first = m + 1
    for group in GROUPS:
        edges, tag = mesh.groups[group], BOUNDARY_TAGS[group]
        if not len(edges):
            continue
        gmsh.model.addDiscreteEntity(1, tag)
        gmsh.model.mesh.addElementsByType(tag, 1, np.arange(first, first + len(edges)),
                                          (edges + 1).ravel())
        gmsh.model.addPhysicalGroup(1, [tag], tag, name=group)
        first += len(edges)


def read_model() -> QuadMesh:
    """Read the current gmsh model written by :func:`to_gmsh` back into arrays."""
    import gmsh

    tags, xyz, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    nodes = xyz.reshape(-1, 3)[order, :2]
    index = np.empty(int(tags.max()) + 1, dtype=np.int64)
    index[tags[order]] = np.arange(len(order))

    def elements(dim: int, tag: int, etype: int, width: int) -> np.ndarray:
        out = [np.empty((0, width), np.int64)]
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            _, conn = gmsh.model.mesh.getElementsByType(etype, int(entity))
            out.append(index[np.asarray(conn, dtype=np.int64)].reshape(-1, width))
        return np.concatenate(out)

    groups = {}
    present = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
    for group in GROUPS:
        groups[group] = (elements(1, present[group][1], 1, 2) if group in present
                         else np.empty((0, 2), np.int64))
    return QuadMesh(nodes, elements(2, present["domain"][1], 3, 4), groups)
