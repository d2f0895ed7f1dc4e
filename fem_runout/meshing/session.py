"""A quiet, deterministic gmsh session."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["VERBOSE_ENV", "gmsh_session"]

VERBOSE_ENV = "FEM_RUNOUT_GMSH_VERBOSE"  # set to 1 to see gmsh's messages on the terminal


@contextmanager
def gmsh_session(verbose: bool | None = None) -> Iterator[None]:
    """Initialize gmsh for the block (finalize it after, unless it was already running).

    gmsh prints nothing (``General.Terminal = 0``) unless ``verbose`` is true or the
    environment variable ``FEM_RUNOUT_GMSH_VERBOSE`` is ``1``; it runs on one thread
    (``General.NumThreads = 1``) so that a case always gives the same mesh, and does not take
    over SIGINT (the runner handles signals).

    Args:
        verbose: Print gmsh's messages (default: from ``FEM_RUNOUT_GMSH_VERBOSE``).
    """
    import gmsh

    if verbose is None:
        verbose = os.environ.get(VERBOSE_ENV, "0") not in ("", "0")
    started = not gmsh.isInitialized()
    if started:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
    gmsh.option.setNumber("General.Verbosity", 5 if verbose else 1)
    gmsh.option.setNumber("General.NumThreads", 1)
    try:
        yield
    finally:
        if started and gmsh.isInitialized():
            gmsh.finalize()
