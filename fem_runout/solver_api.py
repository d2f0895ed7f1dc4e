"""The contract between a method's solver and everything else (runner, outputs, bench).

A method (:mod:`fem_runout.methods`) builds an object that follows :class:`Solver`: the runner
(:mod:`fem_runout.runner`), the outputs and diagnostics (:mod:`fem_runout.output`), ``compare``
and every bench command use nothing else. Methods that carry material points also follow
:class:`ParticleSolver` (``Method.particles``), which the particle output reads.

Queries (``stable_dt``, ``health``, ``snapshot``, ``n_particles``) change no state: calling
them any number of times leaves the next ``advance`` identical (tested for every registered
method in ``tests/test_methods.py``).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np
from dolfinx import fem, mesh
from mpi4py import MPI

__all__ = ["ParticleSolver", "Solver"]


@runtime_checkable
class Solver(Protocol):
    """What every method exposes.

    Attributes:
        comm: The communicator of the run.
        mesh: The quadrilateral mesh.
        V: The scalar Q1 space; every field below lives on it.
        fields: Q1 functions ``h``, ``hu``, ``hv``, ``z`` (ghost values up to date after
            ``advance``); outputs read them, only the solver writes them.
        lumped_mass: Lumped Q1 mass (nodal area) for the local nodes, owned then ghosts.
        outflow_volume: Volume that has left through open boundaries so far (global, the same
            on every rank).
        dried_volume: Volume of the films that dried out so far (global; 0 for a method
            that dries none). Volume + outflow + dried is the released volume.
        n_particles: Global particle count (collective), or None for a mesh-only method.
    """

    comm: MPI.Comm
    mesh: mesh.Mesh
    V: fem.FunctionSpace
    fields: dict[str, fem.Function]
    lumped_mass: np.ndarray

    @property
    def outflow_volume(self) -> float:
        """Volume that has left through open boundaries so far [m³] (global)."""
        ...

    @property
    def dried_volume(self) -> float:
        """Volume of the films that dried out so far [m³] (global; 0 if none)."""
        ...

    @property
    def n_particles(self) -> int | None:
        """Global particle count (collective), or None for a mesh-only method."""
        ...

    def stable_dt(self) -> float:
        """Largest stable time step for the current state (collective, same on all ranks)."""
        ...

    def advance(self, dt: float) -> None:
        """Advance the state by ``dt`` (collective)."""
        ...

    def snapshot(self) -> Any:
        """Return a copy of the whole state, for :meth:`restore` (local, no MPI).

        The copy stays valid until the next call: a solver may reuse its memory (the
        runner takes one every step, to restore the last good state).
        """
        ...

    def restore(self, snap: Any) -> None:
        """Return to a :meth:`snapshot` (collective: ghost values are refreshed)."""
        ...

    def save_state(self) -> dict[str, Any]:
        """Return the state for a checkpoint (collective; rank-independent form on rank 0).

        Nodal fields in the global order of :func:`~fem_runout.output.gather.gather_nodal`,
        particles sorted by id; :meth:`load_state` restores it on any number of ranks.
        """
        ...

    def load_state(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`save_state` written on any number of ranks (collective)."""
        ...

    def flow_dofs(self) -> np.ndarray:
        """Owned dofs (sorted local indices) outside which ``h``, ``hu``, ``hv`` are zero.

        Local, no MPI. Outputs and diagnostics do their per-step work on these only, so a dry
        DEM costs them nothing (every owned dof is a valid answer).
        """
        ...

    def health(self, also_max: np.ndarray | None = None) -> str | None:
        """Return a message if the state is bad (NaN, negative depth, collapsed column), else None.

        Collective; the same answer on every rank. One max reduction in the usual case.

        Args:
            also_max: Values the caller wants maximised over the ranks in the same message
                (the runner's speed and stop signal): replaced in place by their maxima.
        """
        ...


@runtime_checkable
class ParticleSolver(Solver, Protocol):
    """A :class:`Solver` that carries material points (``Method.particles``).

    Attributes:
        particles: This rank's particles (:class:`mpm.particles.Particles`).
        grid: Where particles are located on the mesh (:class:`mpm.grid.ParticleGrid`).
    """

    particles: Any
    grid: Any

    def particle_elevation(self) -> np.ndarray:
        """Terrain elevation at this rank's particles (local)."""
        ...
