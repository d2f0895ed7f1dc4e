"""DAMPM: the depth-averaged material point method of the seed (§3.2).

It reuses fem_runout's mesh, Q1 space, initial fields, physics objects (friction, Bingham),
runner and outputs; ``method: mpm`` in a case file selects it. See docs/method.md.
"""

import mpi4py.MPI  # noqa: F401  (DOLFINx needs libmpi loaded first)
