"""The contract between a solver (TG2-PC, DAMPM) and the runner, outputs and diagnostics."""

from __future__ import annotations

from typing import Protocol

import numpy as np
from dolfinx import fem, mesh
from mpi4py import MPI


class Solver(Protocol):
    """What every method exposes to the runner.

    Attributes:
        comm: The communicator of the run.
        mesh: The structured quadrilateral mesh.
        V: The scalar Q1 space; every field below lives on it.
        fields: Q1 functions ``h``, ``hu``, ``hv``, ``z`` (ghost values up to date after
            ``advance``).
        lumped_mass: Lumped Q1 mass (nodal area) for the local nodes, owned then ghosts.
        outflow_volume: Volume that has left through open boundaries so far (global, the same
            on every rank).
    """

    comm: MPI.Comm
    mesh: mesh.Mesh
    V: fem.FunctionSpace
    fields: dict[str, fem.Function]
    lumped_mass: np.ndarray
    outflow_volume: float

    def stable_dt(self) -> float:
        """Largest stable time step for the current state (collective, same on all ranks)."""
        ...

    def advance(self, dt: float) -> None:
        """Advance the state by ``dt`` (collective)."""
        ...
