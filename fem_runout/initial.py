"""Initial state on the Q1 nodes from a case: terrain, depth or free surface, velocity."""

from __future__ import annotations

import numpy as np


def depth_below_surface(surface: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Depth ``max(surface - z, 0)`` chosen so that ``h + z == surface`` in floating point.

    ``fl(surface - z) + z`` can miss ``surface`` by one unit in the last place; a lake at rest
    whose discrete free surface is not exactly flat is pushed by that round-off. Where it
    misses, the neighbouring floats of ``h`` are tried.

    Args:
        surface: Free-surface elevation per node.
        z: Bed elevation per node.

    Returns:
        Non-negative depth per node.
    """
    surface = np.broadcast_to(np.asarray(surface, dtype=float), z.shape)
    h = np.maximum(surface - z, 0.0)
    for _ in range(2):
        miss = (h > 0.0) & (h + z != surface)
        if not miss.any():
            break
        for direction in (np.inf, -np.inf):
            trial = np.nextafter(h[miss], direction)
            ok = (trial > 0.0) & (trial + z[miss] == surface[miss])
            idx = np.flatnonzero(miss)[ok]
            h[idx] = trial[ok]
            miss[idx] = False
    return h
