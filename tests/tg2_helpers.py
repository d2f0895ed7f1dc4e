"""Shared helpers of the TG2-PC and DAMPM tests (serial and MPI).

The sheet cases and their probe serve the friction tests of both methods
(``tests/test_tg2_physics.py``, ``tests/test_mpm_physics.py``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.config import Case, load_case
from fem_runout.methods import default_method
from fem_runout.references.norms import l1, linf, nodal_weights

CASES = Path(__file__).resolve().parents[1] / "cases"
G = 9.81
#: Probe node x [m] and the interior window [m] of the sheets, away from their boundaries.
PROBE, WINDOW = 300.0, (250.0, 350.0)


def case(name: str, *overrides: str):
    """Load a shipped case with overrides."""
    return load_case(CASES / f"{name}.yaml", overrides=list(overrides))


def sheet(slope: float, friction: dict[str, Any], u0: float = 0.0, h: float = 1.0,
          end: float = 1.0, cells: tuple[int, int] = (800, 2), method: str | None = None,
          right: str = "open") -> Case:
    """A uniform layer on the plane Z = -S x, 400 m long, open downstream.

    Boundary disturbances travel at most at |u| + sqrt(g h) (< 15 m/s here): the probe region
    [250, 350] m sees the uniform layer of the exact solutions for the whole run. ``method``
    defaults to the registry's default method.
    """
    return load_case({
        "name": "sheet", "gravity": G, "method": method or default_method(),
        "domain": {"extent": [0, 400, 0, 4], "cells": list(cells),
                   "boundary": {"left": "wall", "right": right, "bottom": "wall",
                                "top": "wall"}},
        "terrain": {"elevation": f"-{slope} * x"},
        "initial": {"depth": str(h), "velocity": [str(u0), "0"]},
        "material": {"density": 1200, "friction": friction},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    })


class Probe:
    """Runner callback: velocity of the centre node and the largest speed in the window."""

    def __init__(self) -> None:
        self.t: list[float] = [0.0]
        self.u: list[tuple[float, float]] = []

    def _u(self, s: Any) -> tuple[float, float]:
        x = s.disc.coords
        i = int(np.argmin(np.hypot(x[:, 0] - PROBE, x[:, 1] - 2.0)))
        own = slice(0, s.disc.n_owned_nodes)
        h, hu = s.fields["h"].x.array, s.fields["hu"].x.array
        interior = (x[own, 0] > WINDOW[0]) & (x[own, 0] < WINDOW[1])
        return hu[i] / h[i], np.abs(hu[own][interior] / h[own][interior]).max()

    def start(self, s: Any, i: Any) -> None:
        """Record the initial velocities."""
        self.u.append(self._u(s))

    def step(self, s: Any, i: Any) -> None:
        """Record the time and the velocities after a step."""
        self.t.append(i.t)
        self.u.append(self._u(s))

    def output(self, s: Any, i: Any) -> None:
        """Nothing to write."""

    def finish(self, s: Any, i: Any) -> None:
        """Nothing to close."""


def probe(c: Case) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run ``c`` serially with a :class:`Probe`: times, probe velocity, max window speed."""
    from mpi4py import MPI

    from fem_runout.api import build_solver
    from fem_runout.runner import Runner, Schedule

    solver = build_solver(c, MPI.COMM_SELF)
    p = Probe()
    Runner(solver, Schedule(c.time.end, c.time.cfl, c.output.every), [p]).run()
    return np.array(p.t), np.array([u for u, _ in p.u]), np.array([m for _, m in p.u])


def lake_errors(result, level: float = 10.0, dry: float = 1e-6) -> dict[str, tuple[float, float]]:
    """(L1, Linf) of the free-surface error on wet nodes and of the momenta."""
    w = nodal_weights(result.x, result.y)
    wet = result.h > dry
    eta = np.where(wet, result.h + result.z - level, 0.0)
    return {
        "eta": (l1(eta, w), linf(eta)),
        "hu": (l1(result.hu, w), linf(result.hu)),
        "hv": (l1(result.hv, w), linf(result.hv)),
    }


def assert_same_on_ranks(c, world, tol: float = 1e-10, serial=None):
    """Run ``c`` on ``world`` and serially; on rank 0 assert the results agree (collective).

    Same steps and particle count (None for mesh methods), same node order, fields and
    peaks within ``tol`` relative, same final volume and mass error to 1e-12; with
    ``tol = 0`` the series' volume, kinetic energy and wet area bit for bit at every step.

    Args:
        c: The case.
        world: The communicator of the parallel run.
        tol: Relative tolerance of the fields (0: the same bits).
        serial: The serial run of ``c`` on rank 0 if already done
            (:func:`tests.serial_runs.serial_references`); run here if None.

    Returns:
        The parallel result on rank 0, None elsewhere.
    """
    from mpi4py import MPI

    from fem_runout.api import run

    par = run(c, write=False, comm=world)
    if world.rank != 0:
        return None
    ser = serial if serial is not None else run(c, write=False, comm=MPI.COMM_SELF)
    assert par.steps == ser.steps and par.particles == ser.particles
    np.testing.assert_allclose(par.x, ser.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(par.y, ser.y, rtol=0, atol=1e-12)
    for key in ("h", "hu", "hv", "peak_depth", "peak_speed"):
        a, b = getattr(par, key), getattr(ser, key)
        diff = np.abs(a - b).max()
        print(f"{c.method} {key}: max |parallel - serial| = {diff:.2e}")
        assert diff <= tol * max(1.0, np.abs(b).max()), key
    volume = max(1.0, ser.series["volume"][0])
    assert abs(par.series["volume"][-1] - ser.series["volume"][-1]) <= 1e-12 * volume
    assert abs(par.series["mass_error"][-1] - ser.series["mass_error"][-1]) < 1e-12
    if tol == 0.0:  # the same bits: so are the diagnostics' exact-fold sums, at every step
        for key in ("volume", "kinetic_energy", "wet_area"):
            assert np.array_equal(par.series[key], ser.series[key]), key
    return par
