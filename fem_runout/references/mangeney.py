"""Dam break on an incline with Coulomb friction (Mangeney et al. 2000, J. Geophys. Res. 105).

Mangeney et al. write the Savage–Hutter equations in slope-aligned coordinates and find, for a
reservoir ``h0`` released on a dry slope of angle θ with friction angle δ, a Ritter fan in a
frame with constant acceleration: ``h = (2 c0 - x/t - m t/2)²/(9 g cosθ)`` with
``m = g sinθ - g cosθ tanδ`` (here taken positive downslope) and ``c0 = sqrt(g h0 cosθ)``.

**Horizontal-coordinate form (seed eq. 1).** Our equations have gravity ``g`` along -z, the bed
``Z = -S x`` (``S = tanθ``) and Coulomb friction ``-g μ h v/|v|`` (normal stress ``ρ g h``, see
``physics/friction/``). In 1D with ``u > 0``::

    ∂t h + ∂x(h u) = 0,   ∂t(h u) + ∂x(h u² + g h²/2) = g h (S - μ) = m h,   m = g (S - μ)

A constant body acceleration ``m`` is removed by ``ξ = x - m t²/2``, ``w = u - m t``, which
leaves the flat frictionless equations. Hence Ritter's solution rides on the accelerating frame
(``c0 = sqrt(g h0)``, reservoir on ``x <= x0``)::

    s = (x - x0 - m t²/2)/t
    h = h0                         s <= -c0
    h = (2 c0 - s)²/(9 g)           -c0 < s < 2 c0
    h = 0                          s >= 2 c0
    u = m t + 2/3 (s + c0)         (fan), m t in the reservoir

which is Mangeney's formula with ``cosθ → 1`` (horizontal coordinates measure depth vertically
and the normal stress of eq. 2 is ``ρ g h``). It needs ``S > μ`` (the whole mass moves downslope,
so the Coulomb sign is constant). A wall upstream at ``x_L`` disturbs the reservoir only behind
``x_L + m t²/2 + c0 t``.
"""

from __future__ import annotations

import math

import numpy as np


def acceleration(slope: float, mu: float, g: float = 9.81) -> float:
    """Frame acceleration ``m = g (S - μ)`` [m/s²]."""
    return g * (slope - mu)


def depth(x: np.ndarray, t: float, h0: float, x0: float, slope: float, mu: float,
          g: float = 9.81) -> np.ndarray:
    """Exact depth at ``x`` and ``t > 0`` (infinite reservoir ``h0`` on ``x <= x0``)."""
    c0 = math.sqrt(g * h0)
    s = (np.asarray(x, dtype=float) - x0 - 0.5 * acceleration(slope, mu, g) * t * t) / t
    fan = (2.0 * c0 - s) ** 2 / (9.0 * g)
    return np.where(s <= -c0, h0, np.where(s >= 2.0 * c0, 0.0, fan))


def front(t: float, h0: float, x0: float, slope: float, mu: float, g: float = 9.81) -> float:
    """Tip of the dry-bed front ``x0 + 2 c0 t + m t²/2`` [m]."""
    return x0 + 2.0 * math.sqrt(g * h0) * t + 0.5 * acceleration(slope, mu, g) * t * t


def valid_from(t: float, h0: float, slope: float, mu: float, x_left: float = 0.0,
               g: float = 9.81) -> float:
    """Smallest x not yet reached by the disturbance of the upstream wall at ``x_left``."""
    return x_left + 0.5 * acceleration(slope, mu, g) * t * t + math.sqrt(g * h0) * t


H0, X0, SLOPE, MU, END, LENGTH = 1.0, 20.0, 0.5, 0.2, 2.0, 50.0


def case_dict(cells: int, g: float = 9.81) -> dict:
    """Reservoir 1 m deep on [0, 20] m of the slope Z = -0.5 x, μ = 0.2, t = 2 s, 50 m × 1 m.

    The node on the dam carries half the depth (the Q1 interpolant holds the exact volume).
    """
    dx = LENGTH / cells
    eps = 1e-4 * dx
    return {
        "name": "mangeney", "gravity": g,
        "domain": {"extent": [0, LENGTH, 0, 1], "cells": [cells, 2],
                   "boundary": {"left": "wall", "right": "open", "bottom": "wall",
                                "top": "wall"}},
        "terrain": {"elevation": f"-{SLOPE} * x"},
        "initial": {"depth": f"where(x < {X0 - eps}, {H0}, where(x < {X0 + eps}, {H0 / 2}, 0))",
                    "velocity": ["0", "0"]},
        "material": {"density": 1000, "friction": {"law": "coulomb", "mu": MU}},
        "time": {"end": END, "cfl": 0.9}, "output": {"every": END},
    }
