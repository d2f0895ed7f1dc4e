"""Set up the DAMPM solver of a case: the same mesh, Q1 space, initial fields and physics as TG2."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fem_runout.config import Case
from fem_runout.problem import build_problem
from mpm.grid import ParticleGrid
from mpm.mesh_grid import MeshParticleGrid
from mpm.migrate import balanced_destinations, migrate
from mpm.particles import seed_particles
from mpm.solver import MPMSolver

__all__ = ["build_mpm", "still_water_depth"]


def still_water_depth(case: Case, comm: MPI.Comm, coords: np.ndarray,
                      h: np.ndarray) -> np.ndarray | None:
    """Return the nodal still-water depth ``H`` of seed eq. 46, or None.

    A case has a still-water level when its initial state is given as a free surface that is
    the same constant everywhere (e.g. ``free_surface: "10"``); then ``H`` is the initial
    depth ``max(level - Z, 0)`` (bitwise the nodal depth the particles are seeded from).
    """
    surface_fn = case.initial.free_surface_fn()
    if surface_fn is None:
        return None
    eta = np.broadcast_to(np.asarray(surface_fn(coords[:, 0], coords[:, 1]), float), h.shape)
    lo = comm.allreduce(float(eta.min(initial=np.inf)), op=MPI.MIN)
    hi = comm.allreduce(float(eta.max(initial=-np.inf)), op=MPI.MAX)
    return h.copy() if lo == hi else None


def build_mpm(case: Case, comm: MPI.Comm) -> MPMSolver:
    """Create the DAMPM solver of a case (collective): the shared setup plus particles."""
    pb = build_problem(case, comm)
    disc, init = pb.disc, pb.init
    grid = ParticleGrid(disc) if disc.structured else MeshParticleGrid(disc)
    still = still_water_depth(case, comm, disc.coords, init["h"])
    # Gauss points make the lake at rest exact; elsewhere the alias-free uniform lattice
    layout = "uniform" if still is None else "gauss"
    num = case.numerics
    particles = seed_particles(grid, init["h"], *pb.velocity, num.particles_per_direction,
                               layout, num.dry_tolerance)
    particles, _ = migrate(grid, particles, balanced_destinations(grid, particles))
    return MPMSolver(disc, grid, particles, init["z"], case.material.density, pb.gravity,
                     pb.friction, pb.rheology, still, num.flip, num.particles_per_direction,
                     pb.thin_depth, pb.slope, num.transfer == "apic", num.depth_cap)
