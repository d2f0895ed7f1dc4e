"""One runner for every method: owns time, the output schedule, health checks and progress.

The loop asks the solver for ``stable_dt()``, shortens the step to land on output times and
the end time, calls ``advance(dt)`` and then the callbacks. It does no I/O itself.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fem_runout.callbacks import Callback, StepInfo, flow_index
from fem_runout.errors import SimulationError
from fem_runout.exact_sum import exact_total
from fem_runout.solver_api import Solver


@dataclass(frozen=True)
class Schedule:
    """Time control of a run.

    Attributes:
        end: Final time [s].
        cfl: Fraction of the solver's stable step.
        every: Output interval [s].
        max_steps: Stop after this many steps (None: no limit).
        dt_max: Upper bound of the step [s] (None: no bound).
        rest_speed: Stop once the largest speed stays below this [m/s] (None: run to end).
        rest_duration: ... for this long [s].
        rest_depth: Only nodes deeper than this [m] count for the largest speed.
        rest_energy: Also at rest when the kinetic energy is below this fraction of its peak
            (None: speed criterion only).
    """

    end: float
    cfl: float
    every: float
    max_steps: int | None = None
    dt_max: float | None = None
    rest_speed: float | None = None
    rest_duration: float = 0.0
    rest_depth: float = 1e-3
    rest_energy: float | None = None


def max_speed(solver: Solver, depth: float) -> float:
    """Largest nodal speed ``|(hu, hv)| / h`` over nodes with ``h > depth`` (collective)."""
    return motion(solver, depth)[0]


def motion(solver: Solver, depth: float, energy: bool = False) -> tuple[float, float]:
    """Largest speed and (if ``energy``) ``Σ M |q|² / h`` over nodes deeper than ``depth``.

    The second value is twice the kinetic energy divided by the density (0 if not asked),
    summed exactly (:func:`~fem_runout.exact_sum.exact_total`): the rest criterion compares
    it with a fraction of its peak, and a sum with the bits of the partition would stop the
    run one step earlier or later on another rank count. Collective: one max reduction,
    plus one sum reduction with ``energy``.
    """
    from mpi4py import MPI

    imap = solver.V.dofmap.index_map
    idx = flow_index(solver)  # the state is zero elsewhere
    h, hu, hv = (solver.fields[k].x.array[idx].real for k in ("h", "hu", "hv"))
    wet = h > depth
    q2 = hu[wet] ** 2 + hv[wet] ** 2
    terms = np.asarray(solver.lumped_mass)[idx][wet] * q2 / h[wet] if energy else q2[:0]
    local = np.array([float(np.sqrt(np.max(q2 / h[wet] ** 2))) if wet.any() else 0.0,
                      float(np.max(terms, initial=0.0))])
    solver.comm.Allreduce(MPI.IN_PLACE, local, op=MPI.MAX)
    if not energy:
        return float(local[0]), 0.0
    return float(local[0]), exact_total(terms, float(local[1]), imap.size_global, solver.comm)


class Runner:
    """Drive a solver through a schedule with callbacks.

    Attributes:
        info: Where the run is (the last good step after a SimulationError).
        wall_time: Seconds spent in :meth:`run`.
        at_rest: The run stopped because the flow came to rest.

    Args:
        solver: Any object following :class:`~fem_runout.solver_api.Solver`.
        schedule: Time control.
        callbacks: Outputs and diagnostics, called in order.
        progress: Optional object with ``update(info)`` and ``close()`` (rank 0 progress bar).
    """

    def __init__(
        self, solver: Solver, schedule: Schedule, callbacks: Sequence[Callback], progress=None
    ) -> None:
        self.solver = solver
        self.schedule = schedule
        self.callbacks = list(callbacks)
        self.progress = progress
        self.wall_time = 0.0
        self.at_rest = False
        self.info = StepInfo(0.0, 0.0, 0)
        self._rest_since: float | None = None
        self._peak_energy = 0.0

    def _call(self, hook: str, info: StepInfo) -> None:
        for cb in self.callbacks:
            getattr(cb, hook)(self.solver, info)

    def run(self) -> StepInfo:
        """Run to the end time or to rest (collective); raise SimulationError on a bad state.

        With ``schedule.rest_speed`` set, the run stops after the step at which the largest
        speed has stayed below it for ``rest_duration`` seconds (:attr:`at_rest` is then True).
        """
        s, solver = self.schedule, self.solver
        start = time.perf_counter()
        info = self.info = StepInfo(0.0, 0.0, 0)
        self._call("start", info)
        self._call("output", info)
        n_out, last_output = 1, 0.0
        eps = 1e-12 * max(s.end, 1.0)
        while info.t < s.end - eps and (s.max_steps is None or info.step < s.max_steps):
            snap = solver.snapshot()
            clock = time.perf_counter()
            dt = self._next_dt(info.t, n_out * s.every)
            solver.advance(dt)
            clock = time.perf_counter() - clock
            problem = solver.health()
            if problem is not None:
                solver.restore(snap)
                self._call("output", info)
                self._call("finish", info)
                raise SimulationError(
                    f"stopped at t = {info.t:.6g} s (step {info.step + 1}): {problem}; the last "
                    "good state was saved"
                )
            info = self.info = StepInfo(info.t + dt, dt, info.step + 1, clock)
            self._call("step", info)
            if info.t >= n_out * s.every - eps or info.t >= s.end - eps:
                self._call("output", info)
                last_output = info.t
                n_out = math.floor(info.t / s.every + 1e-9) + 1
            if self.progress is not None:
                self.progress.update(info)
            if self._came_to_rest(info):
                break
        self.wall_time = time.perf_counter() - start
        if last_output != info.t:
            self._call("output", info)
        self._call("finish", info)
        if self.progress is not None:
            self.progress.close()
        return info

    def _came_to_rest(self, info: StepInfo) -> bool:
        """Whether the flow has been at rest for ``rest_duration`` (collective, no I/O).

        At rest: the largest speed is below ``rest_speed``, or (with ``rest_energy``) the
        kinetic energy is below ``rest_energy`` times its peak so far.
        """
        s = self.schedule
        if s.rest_speed is None:
            return False
        speed, energy = motion(self.solver, s.rest_depth, s.rest_energy is not None)
        self._peak_energy = max(self._peak_energy, energy)
        slow = s.rest_energy is not None and energy < s.rest_energy * self._peak_energy
        if speed >= s.rest_speed and not slow:
            self._rest_since = None
            return False
        if self._rest_since is None:
            self._rest_since = info.t
        self.at_rest = info.t - self._rest_since >= s.rest_duration - 1e-12
        return self.at_rest

    def _next_dt(self, t: float, next_output: float) -> float:
        s = self.schedule
        dt = s.cfl * self.solver.stable_dt()
        if s.dt_max is not None:
            dt = min(dt, s.dt_max)
        target = min(next_output, s.end)
        if not math.isfinite(dt) or dt >= target - t:
            return target - t
        if t + 1.5 * dt > target:  # avoid a sliver step before an output time
            return 0.5 * (target - t)
        return dt
