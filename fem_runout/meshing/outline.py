"""Quadrilateral mesh of a polygon outline with gmsh (``domain.outline``).

The polygon (and its holes) becomes a plane surface of straight lines, one per outline edge,
so the mesh covers exactly the polygon. gmsh meshes it with triangles at twice the sizes the
fields ask for (``Mesh.MeshSizeFactor = 2``), recombines them pairwise into quadrilaterals
(Blossom, ``Mesh.RecombinationAlgorithm = 1``) and splits every cell into quadrilaterals
(``Mesh.SubdivisionAlgorithm = 1``: a quadrilateral into 4, a leftover triangle into 3), so the
result is quadrilaterals only, of about the asked sizes, with no parity condition on the
boundary (gmsh's own full-quad recombination needs an even number of segments on every
curve). The attempts of :data:`ALGORITHMS` are tried in turn until the result is valid.
Refine lines are helper curves outside the surface: they only feed the Distance fields and
are dropped with the rest of the helper model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from fem_runout.errors import CaseError
from fem_runout.meshing.fields import add_size_fields
from fem_runout.meshing.quadmesh import QuadMesh, finish_mesh, mesh_quality
from fem_runout.meshing.shapes import case_line, case_outline
from fem_runout.meshing.smoothing import equalize_sizes

if TYPE_CHECKING:
    from fem_runout.config import Case
    from fem_runout.config.domain import DomainSpec

__all__ = ["ALGORITHMS", "MESH_OPTIONS", "mesh_outline"]

#: Attempts in turn: (2D algorithm, options over MESH_OPTIONS). First Frontal-Delaunay for
#: quads with Blossom full-quad recombination and no subdivision (the best cells: on the
#: hemisphere's disc angles 40-141 deg, scaled Jacobian >= 0.63); it leaves a triangle where
#: the boundary has an odd number of segments, and then the triangles of Frontal-Delaunay,
#: Frontal-Delaunay for quads or Delaunay are paired and every cell split into quadrilaterals
#: (always all-quad, but angles down to 20 deg and up to 177 deg there).
FULL_QUAD = {"Mesh.RecombinationAlgorithm": 2, "Mesh.SubdivisionAlgorithm": 0,
             "Mesh.MeshSizeFactor": 1, "Mesh.Smoothing": 10}
ALGORITHMS: tuple[tuple[int, dict[str, float]], ...] = ((8, FULL_QUAD), (6, {}), (8, {}), (5, {}))

MESH_OPTIONS: dict[str, float] = {
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.RecombineAll": 1,
    "Mesh.RecombinationAlgorithm": 1,  # Blossom
    "Mesh.SubdivisionAlgorithm": 1,  # then split every cell into quadrilaterals ...
    "Mesh.MeshSizeFactor": 2,  # ... of half the size: mesh at twice the size first
    "Mesh.Smoothing": 3,
    "Mesh.ElementOrder": 1,
    "Mesh.MeshSizeFromPoints": 0,
    "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.MeshSizeExtendFromBoundary": 0,
}


def _loop(ring: np.ndarray) -> int:
    """Add a closed loop of straight lines through ``ring`` (first point not repeated)."""
    import gmsh

    points = [gmsh.model.geo.addPoint(float(x), float(y), 0.0) for x, y in ring]
    lines = [gmsh.model.geo.addLine(points[i], points[(i + 1) % len(points)])
             for i in range(len(points))]
    return gmsh.model.geo.addCurveLoop(lines)


def _surface(poly: Any) -> int:
    """Add the plane surface of a shapely polygon with its holes."""
    import gmsh
    import shapely

    poly = shapely.orient_polygons(poly)  # exterior counterclockwise, holes clockwise
    rings = [np.asarray(r.coords)[:-1, :2] for r in (poly.exterior, *poly.interiors)]
    return gmsh.model.geo.addPlaneSurface([_loop(r) for r in rings])


def _polyline(coords: np.ndarray) -> tuple[list[int], float]:
    """Add helper curves along a line (not in the domain); return them, the longest length."""
    import gmsh

    points = [gmsh.model.geo.addPoint(float(x), float(y), 0.0) for x, y in coords[:, :2]]
    curves = [gmsh.model.geo.addLine(a, b) for a, b in zip(points[:-1], points[1:], strict=True)]
    longest = float(np.linalg.norm(np.diff(coords[:, :2], axis=0), axis=1).max())
    return curves, longest


def _options(d: DomainSpec) -> None:
    import gmsh

    assert d.cell_size is not None and d.min_size is not None
    for name, value in MESH_OPTIONS.items():
        gmsh.option.setNumber(name, value)
    gmsh.option.setNumber("Mesh.MeshSizeMin", d.min_size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", d.cell_size)


def _quads(surface: int) -> tuple[np.ndarray, np.ndarray]:
    """Node coordinates and quadrilaterals (0-based) of the meshed surface."""
    import gmsh

    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    types, _, conns = gmsh.model.mesh.getElements(2, surface)
    found = {int(t): c for t, c in zip(types, conns, strict=True)}
    if set(found) != {3}:
        left = {gmsh.model.mesh.getElementProperties(t)[0]: len(c) for t, c in found.items()
                if t != 3}
        raise CaseError(f"domain.outline: gmsh could not make quadrilaterals only (left {left}); "
                        "try another cell_size or min_size, or simplify the outline")
    return xyz.reshape(-1, 3)[:, :2], index[np.asarray(found[3], dtype=np.int64)].reshape(-1, 4)


def _check_cover(mesh: QuadMesh, poly: Any) -> None:
    """Refuse a mesh whose cells overlap (their areas add up to more than the outline's)."""
    area = mesh_quality(mesh.nodes, mesh.quads)["area"]
    if abs(area - poly.area) > 1e-9 * poly.area:
        raise CaseError(f"domain.outline: the quadrilaterals fold over each other (their area "
                        f"{area:.10g} m² differs from the outline's {poly.area:.10g} m²); "
                        f"{_sharpest(poly)}")


def _sharpest(poly: Any) -> str:
    """Describe the sharpest corner of the outline (what makes quadrilateral meshing fail)."""
    ring = np.asarray(poly.exterior.coords)[:-1, :2]
    a, b = np.roll(ring, 1, axis=0) - ring, np.roll(ring, -1, axis=0) - ring
    cos = (a * b).sum(axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    i = int(np.argmin(angle))
    return (f"its sharpest corner is {angle[i]:.3g} deg at ({ring[i, 0]:.6g}, {ring[i, 1]:.6g}): "
            "round off sharp corners and spikes, or use a smaller min_size/refine size there")


def _attempt(surface: int, poly: Any, attempt: tuple[int, dict[str, float]],
             default: str) -> QuadMesh:
    """Mesh with one 2D algorithm; raise CaseError unless the result is a valid quad mesh."""
    import gmsh

    algorithm, extra = attempt
    for name, value in {**MESH_OPTIONS, **extra}.items():
        gmsh.option.setNumber(name, value)
    gmsh.option.setNumber("Mesh.Algorithm", algorithm)
    gmsh.model.mesh.clear()
    try:
        gmsh.model.mesh.generate(2)
    except Exception as exc:  # gmsh raises a plain Exception with its last error
        raise CaseError(f"domain.outline: gmsh failed to mesh the outline ({exc}); "
                        f"{_sharpest(poly)}") from None
    nodes, quads = _quads(surface)
    mesh = finish_mesh(nodes, quads, {}, default, "domain.outline")
    _check_cover(mesh, poly)
    return mesh


def _smoothed(mesh: QuadMesh, poly: Any, passes: int) -> QuadMesh:
    """``mesh`` after ``passes`` size-equalising passes (:mod:`fem_runout.meshing.smoothing`)."""
    if passes == 0:
        return mesh
    nodes = equalize_sizes(mesh.nodes, mesh.quads, mesh.boundary_nodes(), passes)
    out = QuadMesh(nodes, mesh.quads, mesh.groups)
    _check_cover(out, poly)
    return out


def mesh_outline(case: Case) -> QuadMesh:
    """Mesh ``domain.outline`` with quadrilaterals graded by ``domain.refine``.

    The 2D algorithms of :data:`ALGORITHMS` are tried in turn until one gives a valid mesh
    (convex quadrilaterals covering the outline exactly once); its interior nodes are then
    moved by ``domain.smoothing`` size-equalising passes (:mod:`fem_runout.meshing.smoothing`).
    gmsh must be initialized (:func:`fem_runout.meshing.gmsh_session`); the helper model and
    views are removed afterwards, the current model is left unchanged.

    Raises:
        CaseError: If no algorithm gives a valid quadrilateral mesh.
    """
    import gmsh

    d = case.domain
    poly = case_outline(case).geom
    previous = gmsh.model.getCurrent()
    gmsh.model.add("fem_runout_outline")
    views: list[int] = []
    try:
        surface = _surface(poly)
        curves = {i: _polyline(np.asarray(case_line(case, i).geom.coords))
                  for i, item in enumerate(d.refine or ()) if item.kind == "line"}
        gmsh.model.geo.synchronize()
        add_size_fields(case, poly, curves, views)
        _options(d)
        error = CaseError("domain.outline: not meshed")
        for attempt in ALGORITHMS:
            try:
                mesh = _attempt(surface, poly, attempt, d.default_boundary)
            except CaseError as exc:
                error = exc
                continue
            return _smoothed(mesh, poly, d.smoothing or 0)
        raise error
    finally:
        for view in views:
            gmsh.view.remove(view)
        gmsh.model.remove()
        if previous in gmsh.model.list():
            gmsh.model.setCurrent(previous)
