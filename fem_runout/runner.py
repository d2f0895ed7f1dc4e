"""One runner for every method: owns time, the output schedule, health checks and progress.

The loop asks the solver for ``stable_dt()``, shortens the step to land on output times and
the end time, calls ``advance(dt)`` and then the callbacks. It does no I/O itself.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from fem_runout.callbacks import Callback, StepInfo, StepReduction
from fem_runout.errors import RunInterrupted, SimulationError
from fem_runout.exact_sum import exact_total, local_folds
from fem_runout.health import locate, motion_terms
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
        max_speed: A node faster than this [m/s] is a bad state (None: no limit).
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
    max_speed: float | None = None


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

    top, terms = local_motion(solver, depth, energy)
    solver.comm.Allreduce(MPI.IN_PLACE, top, op=MPI.MAX)
    return finish_motion(solver, top, terms, energy)


def local_motion(solver: Solver, depth: float, energy: bool) -> tuple[np.ndarray, np.ndarray]:
    """Return this rank's part of :func:`motion` (local): ``([speed, max], energy terms)``."""
    nodes = np.asarray(solver.flow_dofs(), dtype=np.int64)  # the state is zero elsewhere
    h, hu, hv = (solver.fields[k].x.array.real for k in ("h", "hu", "hv"))
    terms = np.empty(nodes.size if energy else 0)
    mass = np.asarray(solver.lumped_mass, dtype=np.float64)
    speed2, big, k = motion_terms(nodes, h, hu, hv, mass, float(depth), energy, terms)
    return np.array([0.0 if speed2 == -math.inf else math.sqrt(speed2), big]), terms[:k]


def finish_motion(solver: Solver, top: np.ndarray, terms: np.ndarray, energy: bool
                  ) -> tuple[float, float]:
    """:func:`motion` from the ranks' maxima ``top`` (collective with ``energy``)."""
    if not energy:
        return float(top[0]), 0.0
    n = solver.V.dofmap.index_map.size_global
    return float(top[0]), exact_total(terms, float(top[1]), n, solver.comm)


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
        checkpoints: Writes checkpoints on schedule, when stopped and when the state goes bad
            (:class:`~fem_runout.checkpoint.Checkpointer`; None: never).
        stop: Returns a signal number once the run was asked to stop (SIGTERM, SIGINT), else
            0; checked after every step on every rank (in the step's one reduction).
    """

    def __init__(
        self, solver: Solver, schedule: Schedule, callbacks: Sequence[Callback], progress=None,
        checkpoints=None, stop: Callable[[], int] | None = None,
    ) -> None:
        self.solver = solver
        self.schedule = schedule
        self.callbacks = list(callbacks)
        # those whose per-step values ride in the step's reductions (:meth:`_check`)
        self._reducing = [cb for cb in self.callbacks if isinstance(cb, StepReduction)]
        self.progress = progress
        self.checkpoints = checkpoints
        self.stop = stop
        self.last_checkpoint = None
        self.wall_time = 0.0
        self.at_rest = False
        self.info = StepInfo(0.0, 0.0, 0)
        self._rest_since: float | None = None
        self._motion: tuple[float, float] | None = None  # motion() of the state, once a step
        self._signal = 0  # the stop signal, reduced once a step
        self._peak_energy = 0.0
        self._n_out, self._last_output = 1, 0.0

    def _call(self, hook: str, info: StepInfo) -> None:
        for cb in self.callbacks:
            getattr(cb, hook)(self.solver, info)

    def state(self) -> dict[str, Any]:
        """Return the runner's part of a checkpoint: clock, output counter and rest test."""
        i = self.info
        return {"t": i.t, "dt": i.dt, "step": i.step, "n_out": self._n_out,
                "last_output": self._last_output, "rest_since": self._rest_since,
                "peak_energy": self._peak_energy}

    def checkpoint(self) -> Any:
        """Write a checkpoint of the current state now (collective); return its path."""
        from fem_runout.callbacks import restartable

        tree = {"runner": self.state(), "solver": self.solver.save_state(),
                "callbacks": {name: cb.save_state() for name, cb in
                              restartable(self.callbacks).items()}}
        self.last_checkpoint = self.checkpoints.write(tree, self.info.step, self.info.t,
                                                      self.solver.comm)
        return self.last_checkpoint

    def _begin(self, resume: dict[str, Any] | None) -> StepInfo:
        """Start callbacks; first output unless resuming a checkpoint's runner state."""
        self._n_out, self._last_output = 1, 0.0
        if resume is None:
            info = self.info = StepInfo(0.0, 0.0, 0)
            self._call("start", info)
            self._call("output", info)
            return info
        info = self.info = StepInfo(float(resume["t"]), float(resume["dt"]), int(resume["step"]))
        self._n_out, self._last_output = int(resume["n_out"]), float(resume["last_output"])
        self._rest_since, self._peak_energy = resume["rest_since"], float(resume["peak_energy"])
        self._call("start", info)
        return info

    def _stopped(self) -> int:
        """Return the signal that asked every rank to stop, or 0 (reduced in :meth:`_check`)."""
        return self._signal  # reduced with the step's checks (:meth:`_check`)

    def _interrupt(self, signum: int, info: StepInfo) -> None:
        path = self.checkpoint() if self.checkpoints is not None else None
        self._call("output", info)
        self._call("finish", info)
        raise RunInterrupted(signum, info.t, info.step, path)

    def run(self, resume: dict[str, Any] | None = None) -> StepInfo:
        """Run to the end time or to rest (collective); raise SimulationError on a bad state.

        With ``schedule.rest_speed`` set, the run stops after the step at which the largest
        speed has stayed below it for ``rest_duration`` seconds (:attr:`at_rest` is then True).

        Args:
            resume: A checkpoint's runner state (:meth:`state`): continue from there; the
                solver and callbacks must have been restored already.
        """
        s, solver = self.schedule, self.solver
        start = time.perf_counter()
        info = self._begin(resume)
        eps = 1e-12 * max(s.end, 1.0)
        while info.t < s.end - eps and (s.max_steps is None or info.step < s.max_steps):
            snap = solver.snapshot()
            clock = time.perf_counter()
            dt = self._next_dt(info.t, self._n_out * s.every)
            solver.advance(dt)
            self._motion = None
            clock = time.perf_counter() - clock
            problem = self._check()
            if problem is not None:
                self._fail(problem, snap, info)
            info = self.info = StepInfo(info.t + dt, dt, info.step + 1, clock)
            self._call("step", info)
            if info.t >= self._n_out * s.every - eps or info.t >= s.end - eps:
                self._call("output", info)
                self._last_output = info.t
                self._n_out = math.floor(info.t / s.every + 1e-9) + 1
            if self.progress is not None:
                self.progress.update(info)
            if self._came_to_rest(info):
                break
            if signum := self._stopped():
                self.wall_time = time.perf_counter() - start
                self._interrupt(signum, info)
            if self.checkpoints is not None and self.checkpoints.due(info.t):
                self.checkpoint()
        self.wall_time = time.perf_counter() - start
        if self._last_output != info.t:
            self._call("output", info)
        self._call("finish", info)
        if self.progress is not None:
            self.progress.close()
        return info

    def _check(self) -> str | None:
        """Check the state's health, the speed limit and the stop signal in one reduction.

        The max reduction of the solver's health flag (:meth:`Solver.health`) also carries the
        largest speed (and kinetic energy term) of :func:`motion`, the signal of ``stop`` and
        the maxima of the :class:`~fem_runout.callbacks.StepReduction` callbacks; one sum
        reduction then carries the kinetic energy (with ``rest_energy``) and the callbacks'
        sums. Returns a message if the state is bad.
        """
        s, solver = self.schedule, self.solver
        self._motion, self._signal = None, 0
        watch = s.max_speed is not None or s.rest_speed is not None or self.stop is not None
        energy = watch and s.rest_speed is not None and s.rest_energy is not None
        parts = [np.asarray(cb.step_maxima(solver), dtype=np.float64) for cb in self._reducing]
        terms = None
        if watch:
            with np.errstate(all="ignore"):  # a bad state is reported by health, not numpy
                top, terms = local_motion(solver, s.rest_depth, energy)
            stop = float(self.stop()) if self.stop is not None else 0.0
            parts.insert(0, np.array([top[0], top[1], stop]))
        checks = np.concatenate(parts) if parts else None
        problem = solver.health(checks)
        if problem is not None:
            return problem
        if not parts:
            return None
        maxima = np.split(checks, np.cumsum([p.size for p in parts])[:-1])
        total = self._reduce_sums(maxima[1:] if watch else maxima,
                                  terms if energy else None, float(checks[1]) if watch else 0.0)
        if not watch:
            return None
        self._motion = (float(checks[0]), total)
        self._signal = int(checks[2])
        speed, limit = self._motion[0], s.max_speed
        if limit is not None and speed > limit:
            return f"speed {speed:.4g} m/s above numerics.max_speed = {limit:g} m/s"
        return None

    def _reduce_sums(self, maxima: list[np.ndarray], terms: np.ndarray | None,
                     bound: float) -> float:
        """One sum reduction of the kinetic energy's folds and the callbacks' sums.

        Args:
            maxima: Each :class:`~fem_runout.callbacks.StepReduction` callback's maxima,
                reduced over the ranks.
            terms: This rank's kinetic energy terms (:func:`local_motion`), or None.
            bound: Their bound over the ranks.

        Returns:
            The kinetic energy term's exact total (0 without ``terms``).
        """
        from mpi4py import MPI

        solver = self.solver
        parts = [np.asarray(cb.step_sums(solver, m), dtype=np.float64)
                 for cb, m in zip(self._reducing, maxima, strict=True)]
        if terms is not None:
            n = solver.V.dofmap.index_map.size_global
            parts.insert(0, local_folds([terms], np.array([bound]), n))
        if not parts:
            return 0.0
        sums = np.concatenate(parts)
        solver.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        reduced = np.split(sums, np.cumsum([p.size for p in parts])[:-1])
        if terms is not None:
            total, reduced = float(reduced[0][0] + reduced[0][1]), reduced[1:]
        else:
            total = 0.0
        for cb, m, part in zip(self._reducing, maxima, reduced, strict=True):
            cb.step_reduced(solver, m, part)
        return total

    def _fail(self, problem: str, snap: Any, info: StepInfo) -> None:
        """Name the place, go back to the last good state, save it, raise SimulationError."""
        where = locate(self.solver, self.schedule.rest_depth)
        self.solver.restore(snap)
        saved = "the last good state was saved"
        if self.checkpoints is not None:
            saved += f" (restart from it with changed numerics: --restart {self.checkpoint()})"
        self._call("output", info)
        self._call("finish", info)
        raise SimulationError(f"stopped at t = {info.t:.6g} s (step {info.step + 1}): "
                              f"{problem}{where}; {saved}")

    def _came_to_rest(self, info: StepInfo) -> bool:
        """Whether the flow has been at rest for ``rest_duration`` (collective, no I/O).

        At rest: the largest speed is below ``rest_speed``, or (with ``rest_energy``) the
        kinetic energy is below ``rest_energy`` times its peak so far.
        """
        s = self.schedule
        if s.rest_speed is None:
            return False
        speed, energy = self._motion_now()
        self._peak_energy = max(self._peak_energy, energy)
        slow = s.rest_energy is not None and energy < s.rest_energy * self._peak_energy
        if speed >= s.rest_speed and not slow:
            self._rest_since = None
            return False
        if self._rest_since is None:
            self._rest_since = info.t
        self.at_rest = info.t - self._rest_since >= s.rest_duration - 1e-12
        return self.at_rest

    def _motion_now(self) -> tuple[float, float]:
        """:func:`motion` of the state after the step, computed once per step (:meth:`_check`)."""
        if self._motion is None:
            s = self.schedule
            energy = s.rest_speed is not None and s.rest_energy is not None
            self._motion = motion(self.solver, s.rest_depth, energy)
        return self._motion

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
