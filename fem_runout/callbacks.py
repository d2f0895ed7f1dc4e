"""Callbacks the runner calls: outputs and diagnostics live here, never inside the time loop."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from fem_runout.solver_api import Solver


@dataclass(frozen=True)
class StepInfo:
    """Where the run is.

    Attributes:
        t: Simulated time after the step [s].
        dt: Size of the step just taken (0 before the first step) [s].
        step: Number of steps taken so far.
        solver_seconds: Wall time of the solver's part of the step just taken
            (``stable_dt`` and ``advance``; 0 before the first step) [s].
    """

    t: float
    dt: float
    step: int
    solver_seconds: float = 0.0


class Callback(Protocol):
    """A scheduled action of the runner; every method is collective (called on every rank)."""

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Act once on the initial state (t = 0)."""
        ...

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Act after every time step."""
        ...

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Act at every output time, including t = 0 and the final time."""
        ...

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Act once after the last step."""
        ...


@runtime_checkable
class StepReduction(Protocol):
    """A callback whose per-step values ride in the runner's reductions of the step.

    After every step the runner makes one max reduction (the solver's health, the next step's
    limits, the largest speed, the stop signal) and at most one sum reduction (the kinetic
    energy of the rest test). A callback that needs global maxima and exact sums of the state
    after the step (the series' diagnostics) hands its local parts to these two messages
    instead of sending two of its own, and gets them back before its ``step``:
    :meth:`step_maxima`, then :meth:`step_sums` of the reduced maxima, then
    :meth:`step_reduced` with both reduced. None of the three communicates. Sums must be of
    the exact-fold kind (:func:`fem_runout.exact_sum.local_folds`), whose totals do not depend
    on what else the message carries.
    """

    def step_maxima(self, solver: Solver) -> np.ndarray:
        """Return this rank's values to maximise over the ranks (a float array)."""
        ...

    def step_sums(self, solver: Solver, maxima: np.ndarray) -> np.ndarray:
        """Return this rank's values to sum over the ranks, given the reduced maxima."""
        ...

    def step_reduced(self, solver: Solver, maxima: np.ndarray, sums: np.ndarray) -> None:
        """Take both, reduced over the ranks (called before :meth:`Callback.step`)."""
        ...


def flow_index(solver) -> slice | np.ndarray:
    """Where per-step outputs must look: the solver's ``flow_dofs()``, or the owned slice.

    Fancy indexing costs several times a contiguous pass, so when the flow's dofs are more
    than a quarter of the owned ones the whole owned range is cheaper (zeros elsewhere change
    no maximum, sum or test).
    """
    n = solver.V.dofmap.index_map.size_local
    flow = solver.flow_dofs()
    return slice(0, n) if 4 * flow.size > n else flow


def restartable(callbacks) -> dict:
    """Callbacks with ``save_state()`` and ``resume(state)`` by class name (numbered if repeated).

    ``save_state`` is collective and returns a dict of arrays and numbers (nodal arrays in the
    global order of :func:`~fem_runout.output.gather.gather_nodal`, complete on rank 0);
    ``resume`` takes that dict on every rank before the runner's ``start`` (which must then keep
    the restored state and only reopen files).
    """
    found: dict = {}
    for cb in callbacks:
        if hasattr(cb, "save_state") and hasattr(cb, "resume"):
            name = type(cb).__name__
            k = sum(1 for key in found if key.split("#")[0] == name)
            found[name if k == 0 else f"{name}#{k}"] = cb
    return found


class KeepSolver:
    """Callback that keeps the solver, to sample its fields after a run (bench, tests)."""

    solver = None

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Keep the solver."""
        self.solver = solver

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Nothing per step."""

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Nothing at output times."""

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Keep the solver."""
        self.solver = solver
