"""Time-step limits that both methods share."""

from __future__ import annotations

import math

__all__ = ["acceleration_limit"]


def acceleration_limit(dx: float, gravity: float, slope: float) -> float:
    """Return ``sqrt(Δx / (g S))``: a layer starting at rest on slope S moves ≤ half a cell.

    The wave speed alone (``sqrt(g h)``) allows long steps to thin or resting layers on
    steep beds (a 3 s step to a 1e-4 m film, a 6 s one to a layer at rest on 40°); from rest,
    ``x = ½ g S t²`` stays below ``Δx/2`` with this step. ``inf`` on a flat bed.

    Args:
        dx: Smallest cell size [m].
        gravity: ``g`` [m/s²].
        slope: Steepest bed slope ``|∇Z|`` where the flow is (global maximum).
    """
    return float(math.sqrt(dx / (gravity * slope))) if slope > 0 else math.inf
