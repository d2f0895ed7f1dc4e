"""The setup every method shares: case → discretization → initial state → physics.

A method's builder (:mod:`fem_runout.methods`) starts from :func:`build_problem` and adds only
what is its own (TG2-PC: its transport and diffusion–reaction operators; DAMPM: particles).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from fem_runout.config import Case
from fem_runout.errors import CaseError
from fem_runout.initial import depth_below_surface
from fem_runout.mesh import Discretization, build_discretization
from fem_runout.parallel import agree_on_errors
from fem_runout.partition import cell_partitioner, path_owners
from fem_runout.physics.friction import FrictionLaw, friction_from_spec
from fem_runout.physics.rheology import Bingham, rheology_from_spec
from fem_runout.physics.slope import SlopeGeometry, slope_geometry

__all__ = ["Problem", "build_problem", "discretize", "initial_fields", "resolved_thin_depth"]


@dataclass(frozen=True)
class Problem:
    """A case made discrete: what both methods build on.

    Attributes:
        case: The validated case.
        disc: Mesh, Q1 space and precomputed arrays.
        init: Nodal initial fields ``z``, ``h``, ``hu``, ``hv`` (local nodes).
        velocity: Nodal initial velocity ``(u, v)`` (local nodes).
        gravity: ``g`` [m/s²].
        friction: The bed friction law, or None.
        rheology: The internal rheology, or None.
        slope: The bed geometry of the slope-consistent form, or None (horizontal form).
        thin_depth: The resolved ``numerics.thin_depth`` [m].
    """

    case: Case
    disc: Discretization
    init: dict[str, np.ndarray]
    velocity: tuple[np.ndarray, np.ndarray]
    gravity: float
    friction: FrictionLaw | None
    rheology: Bingham | None
    slope: SlopeGeometry | None
    thin_depth: float


def build_problem(case: Case, comm: MPI.Comm) -> Problem:
    """Discretize ``case`` and set up its initial state and physics (collective)."""
    disc = discretize(case, comm)
    init = agree_on_errors(comm, lambda: initial_fields(case, disc.coords))
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    u_fn, v_fn = case.initial.velocity_fns()
    u = np.broadcast_to(np.asarray(u_fn(x, y), float), x.shape)
    v = np.broadcast_to(np.asarray(v_fn(x, y), float), x.shape)
    num = case.numerics
    slope = slope_geometry(disc, init["z"], case.gravity, case.curvature,
                           case.model.curvature_scale) \
        if case.slope_form else None
    return Problem(
        case=case, disc=disc, init=init, velocity=(u, v), gravity=case.gravity,
        friction=friction_from_spec(case.material.friction, case.gravity, num.dry_tolerance),
        rheology=rheology_from_spec(case.material.rheology, case.material.density),
        slope=slope, thin_depth=resolved_thin_depth(case, comm, init["h"]),
    )


def discretize(case: Case, comm: MPI.Comm) -> Discretization:
    """Mesh the case's domain (collective): the rectangle's grid, or a gmsh quad mesh.

    The rectangle is partitioned along the flow path (:mod:`fem_runout.partition`); a gmsh
    mesh (``domain.outline`` or ``domain.mesh``) is built on rank 0 and distributed by
    DOLFINx (:func:`fem_runout.quadmesh.gmsh_discretization`).
    """
    if getattr(case.domain, "kind", "rectangle") != "rectangle":
        from fem_runout.quadmesh import gmsh_discretization

        return gmsh_discretization(case, comm)
    extent, cells = case.domain.extent, case.domain.resolved_cells
    owners = agree_on_errors(comm, lambda: _path_owners(case, comm.size))
    return build_discretization(comm, extent, cells, dict(case.domain.sides),
                                None if owners is None else cell_partitioner(owners, cells[0]))


def _path_owners(case: Case, nparts: int) -> np.ndarray | None:
    """Ranks of the cells for a case with a release (:mod:`fem_runout.partition`), else None."""
    if nparts < 2 or case.initial.release is None:
        return None
    (xmin, xmax, ymin, ymax), (nx, ny) = case.domain.extent, case.domain.resolved_cells
    dx, dy = (xmax - xmin) / nx, (ymax - ymin) / ny
    jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    centres = np.stack([xmin + (ii.ravel() + 0.5) * dx, ymin + (jj.ravel() + 0.5) * dy], axis=1)
    init = initial_fields(case, centres)
    return path_owners(centres, init["z"], init["h"], (nx, ny), (dx, dy), nparts)


def initial_fields(case: Case, coords: np.ndarray) -> dict[str, np.ndarray]:
    """Terrain, depth and momenta at the nodes from the case (every method starts here).

    The elevation comes from ``terrain.dem`` (bilinear on DEM cell centres) or the
    expression; the depth from ``initial.release`` (polygons, raster), ``initial.depth`` or
    ``initial.free_surface``.
    """
    from fem_runout.terrain import elevation_at, initial_depth_at

    x, y = coords[:, 0], coords[:, 1]
    z = elevation_at(case, x, y)
    depth_fn, surface_fn = case.initial.depth_fn(), case.initial.free_surface_fn()
    released = initial_depth_at(case, x, y)
    if released is not None:
        h = released
    elif depth_fn is not None:
        h = np.asarray(depth_fn(x, y), dtype=float)
        scale = max(float(np.abs(h).max()) if h.size else 0.0, 1.0)
        h[(h < 0) & (h > -1e-12 * scale)] = 0.0  # round-off of the node coordinates
        if (h < 0).any():
            raise CaseError(f"initial.depth: must be >= 0 everywhere, min is {h.min():g}")
    else:
        h = depth_below_surface(surface_fn(x, y), z)
    for key, values in (("terrain.elevation", z), ("initial.depth/free_surface", h)):
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise CaseError(f"{key}: the expression gives NaN or inf at {int(bad.sum())} nodes, "
                            f"e.g. x={x[i]:g}, y={y[i]:g}; it must be finite on the whole domain")
    u_fn, v_fn = case.initial.velocity_fns()
    return {"z": z, "h": h, "hu": h * u_fn(x, y), "hv": h * v_fn(x, y)}


def resolved_thin_depth(case: Case, comm: MPI.Comm, h: np.ndarray) -> float:
    """``numerics.thin_depth``, or 1e-6 × the largest initial depth when unset (collective)."""
    if case.numerics.thin_depth is not None:
        return float(case.numerics.thin_depth)
    return 1e-6 * comm.allreduce(float(h.max()) if h.size else 0.0, op=MPI.MAX)
