"""Quadrilateral meshes of the domain with gmsh: outlines, mesh files, the rectangle.

``domain.outline`` (a polygon) is meshed by gmsh with quadrilaterals graded by the
``domain.refine`` size fields; ``domain.mesh`` reads the user's gmsh file. Either way the result
is a gmsh model that DOLFINx reads::

    from fem_runout.meshing import build_model, gmsh_session

    if comm.rank == 0:
        with gmsh_session():
            build_model(case)
            data = dolfinx.io.gmsh.model_to_mesh(gmsh.model, comm, 0, gdim=2)
    # (the other ranks call model_to_mesh with the same arguments, collectively)

See docs/meshes.md.
"""

from fem_runout.meshing.build import MODEL_NAME, build_model, case_mesh, rectangle_mesh
from fem_runout.meshing.quadmesh import (
    BOUNDARY_TAGS,
    DOMAIN_TAG,
    QuadMesh,
    finish_mesh,
    mesh_quality,
    read_model,
    to_gmsh,
)
from fem_runout.meshing.session import VERBOSE_ENV, gmsh_session

__all__ = [
    "BOUNDARY_TAGS",
    "DOMAIN_TAG",
    "MODEL_NAME",
    "VERBOSE_ENV",
    "QuadMesh",
    "build_model",
    "case_mesh",
    "finish_mesh",
    "gmsh_session",
    "mesh_quality",
    "read_model",
    "rectangle_mesh",
    "to_gmsh",
]
