"""fem_runout: depth-averaged run-out of landslides and debris flows with FEniCSx.

Public API (imported lazily so that the command line stays fast)::

    from fem_runout import load_case, run
    case = load_case("cases/inclined_dam_break.yaml", overrides=["time.end=2"])
    result = run(case)          # collective under MPI; arrays on rank 0
"""

from __future__ import annotations

from typing import Any

# The DOLFINx wheel finds its MPI library through mpi4py: load it before any submodule
# imports DOLFINx (import sorting may put ``import dolfinx`` first in a module).
from mpi4py import MPI as _MPI  # noqa: F401

__all__ = ["load_case", "run"]


def __getattr__(name: str) -> Any:
    if name == "load_case":
        from fem_runout.config import load_case

        return load_case
    if name == "run":
        from fem_runout.api import run

        return run
    raise AttributeError(name)
