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
