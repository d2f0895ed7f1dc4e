"""Hard cases for stability (``cases/hard/*.yaml``): run one and check the criteria.

Criteria (issue 5), checked after every step of the run:

* the run reaches its end time (the runner raises on NaN or negative depth);
* no NaN in ``h``, ``hu``, ``hv`` and ``h >= 0`` at every node;
* volume balance: ``|V(t) + outflow(t) + dried(t) - V0| <= 1e-10 V0`` (outflow is 0 on
  closed domains; dried: the films that dried out);
* ``max speed <= 0.9 (sqrt(2 g ΔZ) + 2 sqrt(g h_max))`` over the run (issue 13: the physical
  bound met with 10 % room, not within round-off of it), with ``ΔZ`` the elevation range of
  the domain and ``h_max`` the largest depth seen (speed on nodes with ``h > front_threshold``);
* cases with a vertical drop (:data:`FREE_FALL`): ``max speed <= 1.1 (sqrt(2 g (Z_top -
  Z_min)) + sqrt(g h0))``, free fall from the top of the release plus its wave speed.

The pit case must also come to rest: final max speed below :data:`REST_SPEED`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HARD_DIR = Path(__file__).resolve().parents[2] / "cases" / "hard"
VOLUME_TOL = 1e-10
REST_SPEED = 1e-3  # m/s, final max speed of the pit case
MUST_STOP = ("hard_pit",)
SPEED_ROOM = 0.9  # max speed <= SPEED_ROOM × the energy bound
FREE_FALL = ("hard_cliff", "hard_drop")
FALL_ROOM = 1.1  # max speed <= FALL_ROOM × free fall plus the release's wave speed

#: (case file stem, method) -> what fails; the tests mark these xfail(strict=True).
KNOWN_FAILURES: dict[tuple[str, str], str] = {}


def hard_case_files() -> list[Path]:
    """Return the hard-case YAML files, sorted by name."""
    return sorted(HARD_DIR.glob("*.yaml"))


class Watch:
    """Callback: minimum depth and NaN count of the owned nodes after every step.

    At start (collective) it also measures the initial state's elevation range, its
    free-fall speed and particle count.

    Args:
        gravity: ``g`` [m/s²].
    """

    def __init__(self, gravity: float) -> None:
        self.gravity = gravity
        self.min_h = math.inf
        self.nan = 0
        self.fall_speed = math.nan
        self.elevation_range = math.nan
        self.particles: int | None = None

    def start(self, solver, info) -> None:
        """Measure the initial state and check it."""
        self.fall_speed = _fall_speed(solver, solver.comm, self.gravity)
        self.elevation_range = _elevation_range(solver, solver.comm)
        self.particles = solver.n_particles  # collective
        self.step(solver, info)

    def step(self, solver, info) -> None:
        """Check the state after a step (local, no communication)."""
        own = slice(0, solver.V.dofmap.index_map.size_local)
        arrays = [solver.fields[k].x.array[own] for k in ("h", "hu", "hv")]
        self.nan += int(sum(np.count_nonzero(~np.isfinite(a)) for a in arrays))
        if arrays[0].size:
            self.min_h = min(self.min_h, float(np.nanmin(arrays[0])))

    def output(self, solver, info) -> None:
        """Nothing at outputs."""

    def finish(self, solver, info) -> None:
        """Nothing at the end."""


@dataclass
class HardResult:
    """Outcome of one hard case (the same on every rank).

    Attributes:
        name: Case name.
        method: Method.
        t: Time reached [s]; end: end time [s].
        steps: Number of steps; wall: wall time of the loop [s].
        min_h: Smallest depth seen; nan: NaN values seen.
        volume_error: max over the run of |V + outflow + dried - V0| / V0.
        max_speed: max over the run of the node speed; speed_bound: the allowed bound.
        fall_speed: free fall from the top of the release to the lowest bed plus the
            release's wave speed, ``sqrt(2 g (Z_top - Z_min)) + sqrt(g h0)``.
        final_speed: max speed at the end.
        particles: initial particle count (None for mesh methods).
        at_rest: The run stopped at rest (``time.end: auto``) before the end time.
        failures: Criteria that failed (empty when the case passes).
    """

    name: str
    method: str
    t: float = 0.0
    end: float = 0.0
    steps: int = 0
    wall: float = 0.0
    min_h: float = math.nan
    nan: int = 0
    volume_error: float = math.nan
    max_speed: float = math.nan
    speed_bound: float = math.nan
    fall_speed: float = math.nan
    final_speed: float = math.nan
    particles: int | None = None
    at_rest: bool = False
    failures: list[str] = field(default_factory=list)


def speed_bound(g: float, dz: float, h_max: float) -> float:
    """``sqrt(2 g ΔZ) + 2 sqrt(g h_max)`` [m/s]."""
    return math.sqrt(2.0 * g * dz) + 2.0 * math.sqrt(g * h_max)


def _elevation_range(solver, comm) -> float:
    from mpi4py import MPI

    z = solver.fields["z"].x.array
    zmax = comm.allreduce(float(z.max()) if z.size else -math.inf, op=MPI.MAX)
    zmin = comm.allreduce(float(z.min()) if z.size else math.inf, op=MPI.MIN)
    return zmax - zmin


def _fall_speed(solver, comm, g: float) -> float:
    """``sqrt(2 g (Z_top - Z_min)) + sqrt(g h0)`` from the initial state (collective)."""
    from mpi4py import MPI

    h, z = solver.fields["h"].x.array, solver.fields["z"].x.array
    wet = h > 0.0
    top = comm.allreduce(float(z[wet].max()) if wet.any() else -math.inf, op=MPI.MAX)
    h0 = comm.allreduce(float(h.max()) if h.size else 0.0, op=MPI.MAX)
    low = comm.allreduce(float(z.min()) if z.size else math.inf, op=MPI.MIN)
    return math.sqrt(2.0 * g * max(top - low, 0.0)) + math.sqrt(g * h0)


def run_hard_case(case, comm) -> HardResult:
    """Run ``case`` with its method through :func:`fem_runout.api.run` and check every criterion.

    One output, at the end time (the hard cases judge the run step by step, not at output
    times); ``end: auto`` stops at rest as in any run. Collective.
    """
    from mpi4py import MPI

    from fem_runout.api import run

    every = case.output.model_copy(update={"every": case.time.end_time})
    case = case.model_copy(update={"output": every})
    watch = Watch(case.gravity)
    r = run(case, write=False, comm=comm, callbacks=[watch], raise_errors=False)
    res = HardResult(case.name, case.method, end=case.time.end_time, t=r.t, steps=r.steps,
                     wall=r.wall_time, particles=watch.particles, fall_speed=watch.fall_speed,
                     at_rest=r.at_rest)
    if r.error is not None:
        res.failures.append(f"stopped: {r.error}")
    res.min_h = comm.allreduce(watch.min_h, op=MPI.MIN)
    res.nan = comm.allreduce(watch.nan, op=MPI.SUM)
    _judge(res, r.series, case, watch.elevation_range)
    return res


def _judge(res: HardResult, s: dict[str, np.ndarray], case, dz: float) -> None:
    """Fill the measured values and the list of failed criteria."""
    res.volume_error = float(np.max(np.abs(s["mass_error"]))) if s["t"].size else math.nan
    res.max_speed = float(np.max(s["max_speed"]))
    res.final_speed = float(s["max_speed"][-1])
    res.speed_bound = speed_bound(case.gravity, dz, float(np.max(s["max_depth"])))
    if res.t < res.end * (1 - 1e-12) and not res.at_rest:
        res.failures.append(f"reached t = {res.t:.4g} < end {res.end:.4g}")
    if res.nan:
        res.failures.append(f"{res.nan} NaN values")
    if not res.min_h >= 0.0:
        res.failures.append(f"negative depth {res.min_h:.3e}")
    if not res.volume_error <= VOLUME_TOL:
        res.failures.append(f"volume error {res.volume_error:.2e} > {VOLUME_TOL:g}")
    if not res.max_speed <= SPEED_ROOM * res.speed_bound:
        res.failures.append(f"max speed {res.max_speed:.3g} > {SPEED_ROOM:g} × bound "
                            f"{res.speed_bound:.3g}")
    if res.name in FREE_FALL and not res.max_speed <= FALL_ROOM * res.fall_speed:
        res.failures.append(f"max speed {res.max_speed:.3g} > {FALL_ROOM:g} × free fall "
                            f"{res.fall_speed:.3g}")
    if res.name in MUST_STOP and not res.final_speed <= REST_SPEED:
        res.failures.append(f"final speed {res.final_speed:.2e} > {REST_SPEED:g} (not at rest)")
