"""Inclined dry-bed dam break of seed §4.1: the exact front tip.

On the plane ``Z = Z0 - x S`` in horizontal coordinates (eq. 1, frictionless), the flow seen
from a frame falling with acceleration ``g S`` is a flat-bed dam break, so the tip of the dry-bed
front moves as Ritter's ``2 c0 t`` plus the free fall ``g S t²/2``:

    x_f(t) = x0 + 2 sqrt(g h0) t + g S t² / 2

For the seed's case ``h(x, 0) = 100 - Z = x/3`` on ``x <= 20`` the layer is not uniform; the
front tip is the characteristic leaving the deepest point of the reservoir edge,
``h0 = 20/3`` m at ``x0 = 20`` m, with ``S = 1/3``: 76.8, 158.4, 264.7 m at 2.75, 5.5, 8.25 s.

The paper's fronts of each method (seed §4.1, Table 1 and text; for comparison, not as a
target) are in the method registry: ``fem_runout.methods.get(name).paper["front"]``.
"""

from __future__ import annotations

import numpy as np


def exact_front(t: float, g: float = 9.81, x0: float = 20.0, h0: float = 20.0 / 3.0,
                slope: float = 1.0 / 3.0) -> float:
    """Exact tip position of the dry-bed front [m] at time ``t`` [s]."""
    return float(x0 + 2.0 * np.sqrt(g * h0) * t + 0.5 * g * slope * t * t)
