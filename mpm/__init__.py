"""DAMPM: the depth-averaged material point method of the seed (§3.2).

It reuses fem_runout's mesh, Q1 space, initial fields, physics objects (friction, Bingham),
runner and outputs; ``method: mpm`` in a case file selects it. See docs/method.md.
"""

import mpi4py.MPI  # noqa: F401  (DOLFINx needs libmpi loaded first)

# drop the cached kernels whose imported modules changed (fem_runout.numba_cache, as
# fem_runout's import does): a script importing only an mpm module (``from mpm.projection
# import GridProjector``) would otherwise run an edited helper module's former machine code
from fem_runout.numba_cache import invalidate_once  # noqa: E402

invalidate_once()
