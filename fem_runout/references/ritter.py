"""Ritter's dry-bed dam break (Ritter 1892): flat, frictionless, 1D.

A still layer ``h0`` on ``x <= x0`` and a dry bed beyond, released at t = 0. With
``c0 = sqrt(g h0)``, for t > 0:

    h = h0                                   for x <= x0 - c0 t
    h = (2 c0 - (x - x0)/t)² / (9 g)          for x0 - c0 t < x < x0 + 2 c0 t
    h = 0                                    for x >= x0 + 2 c0 t
    u = 2/3 ((x - x0)/t + c0)                in the rarefaction fan
"""

from __future__ import annotations

import numpy as np


def ritter_depth(x: np.ndarray, t: float, h0: float, x0: float, g: float) -> np.ndarray:
    """Exact depth at positions ``x`` and time ``t > 0``."""
    c0 = np.sqrt(g * h0)
    xi = (np.asarray(x, dtype=float) - x0) / t
    h = (2.0 * c0 - xi) ** 2 / (9.0 * g)
    return np.where(xi <= -c0, h0, np.where(xi >= 2.0 * c0, 0.0, h))


def ritter_velocity(x: np.ndarray, t: float, h0: float, x0: float, g: float) -> np.ndarray:
    """Exact velocity (zero in the still and dry parts)."""
    c0 = np.sqrt(g * h0)
    xi = (np.asarray(x, dtype=float) - x0) / t
    u = 2.0 / 3.0 * (xi + c0)
    return np.where((xi <= -c0) | (xi >= 2.0 * c0), 0.0, u)
