"""The gmsh model of a case's domain: rectangle, outline or ``.msh`` file."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fem_runout.meshing.cache import cached_mesh
from fem_runout.meshing.mshfile import read_msh
from fem_runout.meshing.outline import mesh_outline
from fem_runout.meshing.quadmesh import GROUPS, QuadMesh, finish_mesh, to_gmsh

if TYPE_CHECKING:
    from fem_runout.config import Case

__all__ = ["MODEL_NAME", "build_model", "case_mesh", "rectangle_mesh"]

MODEL_NAME = "fem_runout"


def rectangle_mesh(case: Case) -> QuadMesh:
    """Return the structured mesh of ``domain.extent`` with ``resolved_cells`` squares.

    Nodes row by row from the south-west corner; each side's edges go to its boundary group.
    """
    d = case.domain
    assert d.extent is not None, "case not resolved"
    (xmin, xmax, ymin, ymax), (nx, ny) = d.extent, d.resolved_cells
    x, y = np.meshgrid(np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1))
    nodes = np.column_stack([x.ravel(), y.ravel()])
    ids = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    quads = np.column_stack([ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(),
                             ids[1:, 1:].ravel(), ids[1:, :-1].ravel()])
    side_nodes = {"bottom": ids[0], "right": ids[:, -1], "top": ids[-1, ::-1],
                  "left": ids[::-1, 0]}
    tagged: dict[str, list[np.ndarray]] = {g: [] for g in GROUPS}
    for side, chain in side_nodes.items():
        tagged[d.sides[side]].append(np.column_stack([chain[:-1], chain[1:]]))
    return finish_mesh(nodes, quads, {g: np.concatenate(e) for g, e in tagged.items() if e},
                       "open", "domain")


def case_mesh(case: Case) -> QuadMesh:
    """Return the checked quadrilateral mesh of a resolved case (gmsh initialized).

    An outline's mesh comes from :func:`fem_runout.meshing.cache.cached_mesh` when the same
    outline, sizes and inputs were meshed before (in this process or on disk).

    Raises:
        CaseError: If the outline cannot be meshed or the mesh file is refused.
        RuntimeError: If gmsh is not initialized.
    """
    import gmsh

    if not gmsh.isInitialized():
        raise RuntimeError("gmsh is not initialized: call inside fem_runout.meshing.gmsh_session()")
    d = case.domain
    if d.kind == "outline":  # kept once made (fem_runout.meshing.cache)
        return cached_mesh(case, mesh_outline)
    if d.kind == "file":
        assert d.mesh is not None
        return read_msh(case.resolve_input(d.mesh), d.default_boundary)
    return rectangle_mesh(case)


def build_model(case: Case) -> None:
    """Fill gmsh's current model with the quadrilateral mesh of ``case.domain``.

    Call on one rank only, inside :func:`fem_runout.meshing.gmsh_session`. The model, named
    ``fem_runout`` (an older one of that name is replaced), holds first-order quadrilaterals
    only (convex, counterclockwise), nodes numbered ``1..N``, the 2D physical group
    ``domain`` (tag 1) and the 1D groups ``open`` (tag 1) and ``wall`` (tag 2), which
    together hold every boundary edge once (an empty one is left out). Hand it to DOLFINx
    with ``dolfinx.io.gmsh.model_to_mesh(gmsh.model, comm, 0, gdim=2)``. The same case gives
    the same model bit for bit.

    Args:
        case: A case from :func:`fem_runout.config.load_case` (resolved).

    Raises:
        CaseError: If the outline cannot be meshed or the mesh file is refused.
        RuntimeError: If gmsh is not initialized.
    """
    import gmsh

    mesh = case_mesh(case)
    while MODEL_NAME in gmsh.model.list():
        gmsh.model.setCurrent(MODEL_NAME)
        gmsh.model.remove()
    to_gmsh(mesh, MODEL_NAME)
