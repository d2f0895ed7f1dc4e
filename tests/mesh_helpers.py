"""Inputs of the meshing tests: outlines, a valley DEM, small gmsh files, case dicts."""

from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.meshing import gmsh_session
from tests.terrain_helpers import RES, X0, Y1, write_dem

#: A convex-ish pentagon outline [m] and a line across it (a refinement corridor).
PENTAGON = [[0, 0], [400, 0], [500, 300], [200, 450], [-50, 250]]
LINE = [[0, 100], [450, 200]]


def outline_case(**domain: Any) -> dict[str, Any]:
    """A case dict meshing :data:`PENTAGON` at 10 m with ``domain`` overrides."""
    base: dict[str, Any] = {"outline": PENTAGON, "cell_size": 10.0}
    return {"name": "outline", "domain": {**base, **domain}, "initial": {"depth": "1"},
            "time": {"end": 1.0}}


def valley_dem(tmp_path: Path, nodata: bool = False) -> Path:
    """A 400 m x 300 m DEM: a plane with a sharp ridge along y = 150 m."""
    rows, cols = 60, 80
    xc = X0 + RES * (np.arange(cols) + 0.5)
    yc = Y1 - RES * (np.arange(rows) + 0.5)
    x, y = np.meshgrid(xc, yc)
    z = 100 + 0.2 * (x - X0) + 30 * np.exp(-(((y - (Y1 - 150)) / 20) ** 2))
    if nodata:
        z[30:33, 40:43] = np.nan
    return write_dem(tmp_path / "dem.tif", z)


def write_msh(path: Path, *, recombine: bool = True, order: int = 1, groups: Any = None,
               dim: int = 2) -> Path:
    """A 30 m x 20 m rectangle meshed by gmsh (transfinite 6 x 4), written to ``path``.

    ``groups``: ``{name: (dim, [entity tags])}``; curves 1..4 are bottom, right, top, left.
    """
    import gmsh

    with gmsh_session():
        gmsh.model.add("test")
        pts = [gmsh.model.geo.addPoint(x, y, 0) for x, y in [(0, 0), (30, 0), (30, 20), (0, 20)]]
        lines = [gmsh.model.geo.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
        surface = gmsh.model.geo.addPlaneSurface([gmsh.model.geo.addCurveLoop(lines)])
        for c, n in zip(lines, (7, 5, 7, 5), strict=True):
            gmsh.model.geo.mesh.setTransfiniteCurve(c, n)
        gmsh.model.geo.mesh.setTransfiniteSurface(surface)
        if recombine:
            gmsh.model.geo.mesh.setRecombine(2, surface)
        gmsh.model.geo.synchronize()
        for name, (d, tags) in (groups or {}).items():
            gmsh.model.addPhysicalGroup(d, tags, name=name)
        gmsh.model.mesh.generate(dim)
        if order > 1:
            gmsh.model.mesh.setOrder(order)
        gmsh.option.setNumber("Mesh.SaveAll", 1)
        gmsh.write(str(path))
    return path


def mesh_case(path: Path, **domain: Any) -> dict[str, Any]:
    """A case dict reading the gmsh file ``path``."""
    return {"name": "m", "domain": {"mesh": str(path), **domain}, "initial": {"depth": "1"},
            "time": {"end": 1.0}}
