"""The user's own gmsh ``.msh`` file (``domain.mesh``): read with gmsh and checked.

Allowed: 2D meshes of first-order quadrilaterals (gmsh element type 3) in the plane z = 0.
1D physical groups named ``open`` and ``wall`` mark boundary edges (2-node lines); boundary
edges in neither get ``domain.boundary``. Other physical groups of dimension 0 or 2 are
ignored; a 1D group with another name is refused (a typo must not pass unnoticed).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.meshing.quadmesh import GROUPS, QuadMesh, finish_mesh
from fem_runout.meshing.session import gmsh_session

__all__ = ["read_msh"]

_QUAD, _LINE = 3, 1  # gmsh element types: 4-node quadrangle, 2-node line
_HINT = ("allowed: first-order quadrilaterals only (gmsh: Mesh.RecombineAll = 1 or "
         "transfinite + Recombine, Mesh.ElementOrder = 1)")


def read_msh(path: Path, default: str, key: str = "domain.mesh") -> QuadMesh:
    """Read and check a gmsh file of quadrilaterals (cached by path and modification time).

    Args:
        path: The ``.msh`` file.
        default: Group (``open``/``wall``) of the boundary edges in no physical group.
        key: Case key named in errors.

    Raises:
        CaseError: Missing or unreadable file, no 2D elements, triangles or higher-order
            cells, 3D cells, nodes off the plane z = 0, groups ``open``/``wall`` that are not
            1D or hold edges off the boundary, non-convex cells.
    """
    if path.suffix.lower() != ".msh":
        raise CaseError(f"{key}: '{path}' is not a gmsh .msh file; allowed: a .msh file "
                        "(MSH 2 or 4, ASCII or binary)")
    if not path.is_file():
        raise CaseError(f"{key}: file '{path}' does not exist")
    nodes, quads, tagged = _read_cached(str(path.resolve()), path.stat().st_mtime_ns, key)
    return finish_mesh(nodes, quads, tagged, default, key)


@functools.lru_cache(maxsize=4)
def _read_cached(path: str, mtime: int, key: str
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    import gmsh

    with gmsh_session():
        previous = gmsh.model.getCurrent()
        gmsh.model.add("fem_runout_read_msh")
        try:
            try:
                gmsh.merge(path)
            except Exception as exc:  # gmsh raises a plain Exception with its last error
                raise CaseError(f"{key}: gmsh cannot read '{path}': {exc}") from None
            return _arrays(key)
        finally:
            gmsh.model.remove()
            if previous in gmsh.model.list():
                gmsh.model.setCurrent(previous)


def _count(etype: int) -> tuple[str, int]:
    import gmsh

    name = gmsh.model.mesh.getElementProperties(etype)[0]
    return name, len(gmsh.model.mesh.getElementsByType(etype)[0])


def _arrays(key: str) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Nodes, quads (0-based) and tagged edges of the current gmsh model."""
    import gmsh

    tags, xyz, _ = gmsh.model.mesh.getNodes()
    if not len(tags):
        raise CaseError(f"{key}: holds no nodes; {_HINT}")
    xyz = xyz.reshape(-1, 3)
    z = xyz[:, 2]
    if np.abs(z).max() > 1e-9 * max(1.0, float(np.abs(xyz[:, :2]).max())):
        raise CaseError(f"{key}: nodes must lie in the plane z = 0 (the elevation comes from "
                        f"terrain), got z in [{z.min():.6g}, {z.max():.6g}]")
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    solids = gmsh.model.mesh.getElementTypes(3)
    if len(solids):
        name, n = _count(int(solids[0]))
        raise CaseError(f"{key}: holds {n} 3D elements ({name}); allowed: a 2D mesh")
    types = [int(t) for t in gmsh.model.mesh.getElementTypes(2)]
    if not types:
        raise CaseError(f"{key}: holds no 2D elements; {_HINT}")
    other = [_count(t) for t in types if t != _QUAD]
    if other:
        found = ", ".join(f"{n} of type '{name}'" for name, n in other)
        raise CaseError(f"{key}: holds 2D elements other than 4-node quadrilaterals ({found}); "
                        f"{_HINT}")
    _, conn = gmsh.model.mesh.getElementsByType(_QUAD)
    quads = index[np.asarray(conn, dtype=np.int64)].reshape(-1, 4)
    return xyz[:, :2].copy(), quads, _tagged(index, key)


def _tagged(index: np.ndarray, key: str) -> dict[str, np.ndarray]:
    """Edges of the 1D physical groups ``open`` and ``wall`` (0-based node indices)."""
    import gmsh

    tagged: dict[str, list[np.ndarray]] = {g: [] for g in GROUPS}
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag)
        if name in GROUPS and dim != 1:
            raise CaseError(f"{key}: physical group '{name}' has dimension {dim}; allowed: "
                            f"'{name}' is a 1D group (curves) of boundary edges")
        if dim != 1:
            continue
        if name not in GROUPS:
            raise CaseError(f"{key}: 1D physical group {tag} is named {name!r}; allowed: 1D "
                            "groups named open or wall (boundary edges)")
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            types, _, conns = gmsh.model.mesh.getElements(1, int(entity))
            for etype, conn in zip(types, conns, strict=True):
                if etype != _LINE:
                    raise CaseError(f"{key}: physical group '{name}' holds elements of type "
                                    f"'{_count(int(etype))[0]}'; allowed: 2-node lines "
                                    "(first order)")
                tagged[name].append(index[np.asarray(conn, dtype=np.int64)].reshape(-1, 2))
    return {g: np.concatenate(e) if e else np.empty((0, 2), np.int64) for g, e in tagged.items()}
