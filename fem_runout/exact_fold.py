"""One term's two folds of an exact sum (:mod:`fem_runout.exact_sum`), compiled.

The scalar helper the compiled exact sums share: DAMPM's particle-to-grid kernels
(:mod:`mpm.kernels`) and the series' diagnostics
(:mod:`fem_runout.output.diagnostics_kernel`).
"""

from __future__ import annotations

import numba

__all__ = ["fold"]


@numba.njit(cache=True, inline="always")
def fold(x, e0, e1):
    """``x`` as two folds ``(hi, lo)`` with the extractors ``e0, e1`` (:mod:`fem_runout.exact_sum`).

    The kernels' helpers take and return scalars only: a helper that takes arrays costs a
    reference-count call per array and call inside the caller's loop (numba does not prune
    them there), which made the force pass nine times slower (session 34).
    """
    hi = (x + e0) - e0
    x -= hi
    return hi, (x + e1) - e1
