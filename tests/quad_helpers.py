"""Unstructured quadrilateral meshes for the tests of the general path (issue 17).

:func:`distorted_rectangle` jitters the interior nodes of a rectangle's grid and hands the mesh
to DOLFINx as an unstructured one (rank 0's arrays, DOLFINx's partitioner); :func:`on_mesh`
makes a run use it in place of the rectangle's grid.
"""

from __future__ import annotations

import contextlib

import basix.ufl
import numpy as np
import ufl
from dolfinx import mesh

import fem_runout.problem as problem
from fem_runout.callbacks import KeepSolver
from fem_runout.output.sampling import ray_front_radii
from fem_runout.quadmesh import KIND_CODES, discretization_from_mesh


def distorted_rectangle(comm, extent, cells, sides, amp=0.0, seed=0, partitioner=None):
    """Return the discretization of a distorted grid (interior nodes moved by ``amp`` cells).

    ``seed`` None: a smooth map (waves along both axes, the boundary kept), else random
    jitter from that seed.
    """
    xmin, xmax, ymin, ymax = extent
    nx, ny = cells
    if comm.rank == 0:
        X, Y = np.meshgrid(np.linspace(xmin, xmax, nx + 1), np.linspace(ymin, ymax, ny + 1))
        inner = np.zeros(X.shape, bool)
        inner[1:-1, 1:-1] = True
        if seed is None:
            xi, eta = (X - xmin) / (xmax - xmin), (Y - ymin) / (ymax - ymin)
            wx = np.sin(np.pi * xi) * np.sin(2 * np.pi * eta) * np.sin(6 * np.pi * xi)
            wy = np.sin(2 * np.pi * xi) * np.sin(np.pi * eta)
        else:
            rng = np.random.default_rng(seed)
            wx, wy = rng.uniform(-1, 1, X.shape), rng.uniform(-1, 1, Y.shape)
        X = X + amp * (xmax - xmin) / nx * wx * inner
        Y = Y + amp * (ymax - ymin) / ny * wy * inner
        x = np.column_stack([X.ravel(), Y.ravel()])
        j, i = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
        v0 = (j * (nx + 1) + i).ravel()
        topo = np.column_stack([v0, v0 + 1, v0 + nx + 1, v0 + nx + 2]).astype(np.int64)
    else:
        x, topo = np.empty((0, 2)), np.empty((0, 4), np.int64)
    domain = ufl.Mesh(basix.ufl.element("Lagrange", "quadrilateral", 1, shape=(2,)))
    part = partitioner or mesh.create_cell_partitioner(mesh.GhostMode.shared_facet, 2)
    msh = mesh.create_mesh(comm, topo, domain, x, part)
    msh.topology.create_entities(1)
    msh.topology.create_connectivity(1, 2)
    fmap = msh.topology.index_map(1)
    nf = fmap.size_local + fmap.num_ghosts
    mid = mesh.compute_midpoints(msh, 1, np.arange(nf, dtype=np.int32))
    kind = np.zeros(nf, np.int64)
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    where = {"left": (0, xmin), "right": (0, xmax), "bottom": (1, ymin), "top": (1, ymax)}
    for name, (axis, value) in where.items():
        kind[np.abs(mid[:, axis] - value) < tol] = KIND_CODES[sides[name]]
    return discretization_from_mesh(comm, msh, kind)


@contextlib.contextmanager
def on_mesh(amp: float, seed: int | None = 0):
    """Within the block, runs mesh their rectangle as a jittered unstructured mesh."""
    original = problem.discretize

    def build(case, comm):
        d = case.domain
        return distorted_rectangle(comm, d.extent, d.resolved_cells, dict(d.sides), amp, seed)

    problem.discretize = build
    try:
        yield
    finally:
        problem.discretize = original


#: Runner callback keeping the solver (to sample its fields after the run).
Keep = KeepSolver


def ray_radii(solver, centre, angles, r_max, threshold, step=0.005):
    """Front radius along rays of the solver's depth (:func:`ray_front_radii`; collective)."""
    return ray_front_radii(solver.disc, solver.fields["h"].x.array, centre, angles, r_max,
                           threshold, step)
