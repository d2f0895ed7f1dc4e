"""Thacker's planar surface in a paraboloid (Thacker 1981; SWASHES, Delestre et al. 2013, §4.2.2).

Frictionless flow in the bowl ``Z(x, y) = -h0 (1 - r²/a²)``, ``r² = (x - L/2)² + (y - L/2)²``.
The free surface stays a plane that rotates with period ``T = 2π/ω``, ``ω = sqrt(2 g h0)/a``,
and the wet region is the disc of radius ``a`` centred at ``η (cos ωt, sin ωt)`` (moving
wet/dry line)::

    h(x, y, t) = max(η h0/a² (2 X cos ωt + 2 Y sin ωt - η) - Z(x, y), 0),  X = x - L/2, Y = y - L/2
    u = -η ω sin ωt,   v = η ω cos ωt          (on the wet disc)

SWASHES parameters: a = 1 m, h0 = 0.1 m, L = 4 m, η = 0.5 (r0 = 0.8 m), g = 9.81 m/s²,
so T = 4.486 s. The exact solution holds for the horizontal-coordinate equations (seed eq. 1)
with ``B^f = 0`` and ``σ = 0``.
"""

from __future__ import annotations

import math

import numpy as np

A, H0, L, ETA = 1.0, 0.1, 4.0, 0.5


def omega(g: float = 9.81, a: float = A, h0: float = H0) -> float:
    """Angular frequency ``ω = sqrt(2 g h0)/a`` [1/s]."""
    return math.sqrt(2.0 * g * h0) / a


def period(g: float = 9.81, a: float = A, h0: float = H0) -> float:
    """Period ``T = 2π/ω`` [s]."""
    return 2.0 * math.pi / omega(g, a, h0)


def elevation_expr(a: float = A, h0: float = H0, length: float = L) -> str:
    """Bowl elevation as a case-file expression."""
    c = length / 2
    return f"-{h0} * (1 - ((x - {c})**2 + (y - {c})**2) / {a}**2)"


def depth(x: np.ndarray, y: np.ndarray, t: float, g: float = 9.81, a: float = A,
          h0: float = H0, length: float = L, eta: float = ETA) -> np.ndarray:
    """Exact depth [m] at time ``t``."""
    w = omega(g, a, h0)
    xc, yc = np.asarray(x) - length / 2, np.asarray(y) - length / 2
    z = -h0 * (1.0 - (xc**2 + yc**2) / a**2)
    surface = eta * h0 / a**2 * (2 * xc * math.cos(w * t) + 2 * yc * math.sin(w * t) - eta)
    return np.maximum(surface - z, 0.0)


def velocity(t: float, g: float = 9.81, a: float = A, h0: float = H0,
             eta: float = ETA) -> tuple[float, float]:
    """Exact (uniform) velocity ``(u, v)`` [m/s] on the wet disc at time ``t``."""
    w = omega(g, a, h0)
    return -eta * w * math.sin(w * t), eta * w * math.cos(w * t)


def case_dict(cells: int, periods: float = 1.0, g: float = 9.81) -> dict:
    """Return the case (mapping for ``load_case``): walls, frictionless, run ``periods`` periods."""
    h_expr = (f"maximum({ETA * H0 / A**2} * (2 * (x - {L / 2}) - {ETA}) - ({elevation_expr()}),"
              " 0)")
    _, v0 = velocity(0.0, g)
    end = periods * period(g)
    return {
        "name": "thacker", "gravity": g,
        "domain": {"extent": [0, L, 0, L], "cells": [cells, cells], "boundary": "wall"},
        "terrain": {"elevation": elevation_expr()},
        "initial": {"depth": h_expr, "velocity": ["0", f"where({h_expr} > 0, {v0!r}, 0)"]},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    }
