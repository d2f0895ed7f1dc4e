"""Shared helpers of the TG2-PC tests (serial and MPI)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fem_runout.config import load_case
from fem_runout.references.norms import l1, linf, nodal_weights

CASES = Path(__file__).resolve().parents[1] / "cases"


def case(name: str, *overrides: str):
    """Load a shipped case with overrides."""
    return load_case(CASES / f"{name}.yaml", overrides=list(overrides))


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


def assert_same_on_ranks(c, world, tol: float = 1e-10):
    """Run ``c`` on ``world`` and serially; on rank 0 assert the results agree (collective).

    Same steps and particle count (None for mesh methods), same node order, fields and
    peaks within ``tol`` relative, same final volume and mass error to 1e-12.

    Returns:
        The parallel result on rank 0, None elsewhere.
    """
    from mpi4py import MPI

    from fem_runout.api import run

    par = run(c, write=False, comm=world)
    ser = run(c, write=False, comm=MPI.COMM_SELF) if world.rank == 0 else None
    if world.rank != 0:
        return None
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
    return par
