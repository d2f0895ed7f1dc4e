"""Exact references of the slope-consistent form (:mod:`fem_runout.physics.slope`).

On the plane ``Z = -tanθ x`` the slope form has ``G = g cos²θ`` (no curvature), Coulomb
friction ``μ g cos²θ`` on the horizontal momentum of a flow going straight down and the
turbulent drag ``g |U|²/ξ`` (``|U| = u/cosθ`` the speed along the bed), so:

* **Voellmy sheet** (uniform layer of slope-normal thickness ``h_n``): along the slope
  ``dU/dt = g (sinθ - μ cosθ) - g U²/(ξ h_n)``, ``U(t) = U_∞ tanh(t/τ)`` with the terminal
  speed ``U_∞ = sqrt(ξ h_n (sinθ - μ cosθ))`` of Voellmy (1955) and slope-following models
  (RAMMS, com1DFA), ``τ = 1/sqrt(a b)``, ``a = g (sinθ - μ cosθ)``, ``b = g/(ξ h_n)``.
* **Energy line** (a thin Coulomb block from a slope onto a flat run-out): the bed reaction
  does no work, friction ``μ g cosθ`` along the bed does ``μ g`` per metre of horizontal
  travel, so the block stops where ``ΔZ = μ ΔL`` (travel angle ``tan α = μ``, as in the
  energy-line models of avalanche practice). Measured on the centre of mass; a finite block
  differs by its pressure energy, ``O(h/L)``.
* **Mangeney's dam break** (Mangeney et al. 2000) on the incline: the 1-D slope form is the
  seed's horizontal system with ``g → g cos²θ`` (pressure and friction alike), so the
  exact solution is :func:`fem_runout.references.mangeney.depth` with that gravity. In
  slope-aligned variables (``ξ = x/cosθ``, ``h_n = h cosθ``) it is Mangeney's solution with
  the acceleration ``g (sinθ - μ cosθ)`` and the spreading speed ``c0 = sqrt(g h_n0/cosθ)``
  where Savage–Hutter has ``sqrt(g h_n0 cosθ)``: the slope form keeps the horizontal lake at
  rest and so carries the pressure ``cos²θ`` less reduced along the slope (docs/method.md).
"""

from __future__ import annotations

import math

import numpy as np

from fem_runout.references import mangeney

# -- Voellmy sheet on 35° ---------------------------------------------------------------------
SHEET_THETA, SHEET_MU, SHEET_XI, SHEET_HN = 35.0, 0.2, 500.0, 1.0
SHEET_WINDOW = (450.0, 650.0)


def sheet_speed(t: float, theta_deg: float = SHEET_THETA, mu: float = SHEET_MU,
                xi: float = SHEET_XI, h_n: float = SHEET_HN, g: float = 9.81) -> float:
    """Exact speed along the bed ``U(t)`` [m/s] of a sheet starting at rest."""
    th = math.radians(theta_deg)
    a, b = g * (math.sin(th) - mu * math.cos(th)), g / (xi * h_n)
    return math.sqrt(a / b) * math.tanh(math.sqrt(a * b) * t)


def sheet_terminal_speed(theta_deg: float = SHEET_THETA, mu: float = SHEET_MU,
                         xi: float = SHEET_XI, h_n: float = SHEET_HN) -> float:
    """``U_∞ = sqrt(ξ h_n (sinθ - μ cosθ))`` [m/s]."""
    th = math.radians(theta_deg)
    return math.sqrt(xi * h_n * (math.sin(th) - mu * math.cos(th)))


def sheet_case(cells: int, g: float = 9.81) -> dict:
    """1 m (slope-normal) sheet on 35°, μ = 0.2, ξ = 500, 800 m × 4 m, to 3 relaxation times.

    Disturbances from the upstream wall travel at most ``u + sqrt(G h)`` < 17 m/s, so the
    window [450, 650] m holds the uniform layer; the open downstream side is supercritical.
    """
    th = math.radians(SHEET_THETA)
    a, b = g * (math.sin(th) - SHEET_MU * math.cos(th)), g / (SHEET_XI * SHEET_HN)
    end = 3.0 / math.sqrt(a * b)
    return {
        "name": "voellmy_slope", "gravity": g,
        "domain": {"extent": [0, 800, 0, 4], "cells": [cells, 2],
                   "boundary": {"left": "wall", "right": "open", "bottom": "wall", "top": "wall"}},
        "terrain": {"elevation": f"-{math.tan(th)!r} * x"},
        "initial": {"depth": repr(SHEET_HN / math.cos(th)), "velocity": ["0", "0"]},
        "material": {"density": 1200,
                     "friction": {"law": "voellmy", "mu": SHEET_MU, "xi": SHEET_XI}},
        "model": {"form": "slope"},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    }


# -- Energy line: Coulomb block, 35° slope onto a flat run-out ---------------------------------
LINE_THETA, LINE_MU, LINE_BEND, LINE_FOOT = 35.0, 0.3, 20.0, 300.0
LINE_BLOCK = (150.0, 170.0, 0.2)  # from, to [m], vertical depth [m]


def line_elevation(x: np.ndarray) -> np.ndarray:
    """``Z = tanθ (L/2) ln(1 + exp(-2 (x - x_f)/L))``: 35° far upslope, flat beyond x_f."""
    s = math.tan(math.radians(LINE_THETA))
    return s * LINE_BEND / 2 * np.log1p(np.exp(-2.0 * (np.asarray(x, float) - LINE_FOOT)
                                               / LINE_BEND))


def line_case(cells: int) -> dict:
    """0.2 m × 20 m Coulomb block (μ = 0.3) released at rest at x = 150–170 m (Z ≈ 98 m)."""
    s = math.tan(math.radians(LINE_THETA))
    x0, x1, h = LINE_BLOCK
    return {
        "name": "energy_line",
        "domain": {"extent": [0, 600, 0, 4], "cells": [cells, 2], "boundary": "wall"},
        "terrain": {"elevation": f"{s * LINE_BEND / 2!r} * log(1 + exp(-2 * (x - {LINE_FOOT})"
                                 f" / {LINE_BEND}))"},
        "initial": {"depth": f"where((x > {x0}) * (x < {x1}), {h}, 0)"},
        "material": {"density": 1000, "friction": {"law": "coulomb", "mu": LINE_MU}},
        # the energy line tan α = μ holds without the centrifugal friction of the bend
        "model": {"form": "slope", "curvature": False},
        "time": {"end": "auto", "max": 120, "rest_speed": 0.01, "rest_duration": 2},
    }


def travel_tangent(x0: np.ndarray, h0: np.ndarray, x1: np.ndarray, h1: np.ndarray,
                   w: np.ndarray) -> float:
    """``tan α`` of the centre of mass between two nodal depth fields (weights ``w``)."""
    m0, m1 = h0 * w, h1 * w
    xa, xb = (m0 * x0).sum() / m0.sum(), (m1 * x1).sum() / m1.sum()
    za = (m0 * line_elevation(x0)).sum() / m0.sum()
    zb = (m1 * line_elevation(x1)).sum() / m1.sum()
    return float((za - zb) / (xb - xa))


# -- Mangeney's dam break on 30° --------------------------------------------------------------
MANG_THETA, MANG_MU, MANG_HN, MANG_X0, MANG_END, MANG_LENGTH = 30.0, 0.2, 1.0, 20.0, 2.0, 60.0


def mangeney_gravity(g: float = 9.81) -> float:
    """``g cos²θ``: the gravity of the equivalent horizontal system."""
    return g * math.cos(math.radians(MANG_THETA)) ** 2


def mangeney_depth(x: np.ndarray, t: float, g: float = 9.81) -> np.ndarray:
    """Exact vertical depth of the slope form (see the module docstring)."""
    th = math.radians(MANG_THETA)
    return mangeney.depth(x, t, MANG_HN / math.cos(th), MANG_X0, math.tan(th), MANG_MU,
                          mangeney_gravity(g))


def mangeney_fronts(t: float, g: float = 9.81) -> tuple[float, float]:
    """Dry-bed tip along the slope ``ξ`` [m]: the slope form's and Savage–Hutter's."""
    th = math.radians(MANG_THETA)
    c, s = math.cos(th), math.sin(th)
    acc = g * (s - MANG_MU * c)
    xi0 = MANG_X0 / c
    ours = xi0 + 2.0 * math.sqrt(g * MANG_HN / c) * t + 0.5 * acc * t * t
    savage_hutter = xi0 + 2.0 * math.sqrt(g * MANG_HN * c) * t + 0.5 * acc * t * t
    return ours, savage_hutter


def mangeney_valid_from(t: float, g: float = 9.81) -> float:
    """Smallest x [m] the upstream wall's disturbance has not reached."""
    th = math.radians(MANG_THETA)
    return mangeney.valid_from(t, MANG_HN / math.cos(th), math.tan(th), MANG_MU, 0.0,
                               mangeney_gravity(g))


def mangeney_case(cells: int, g: float = 9.81) -> dict:
    """1 m (slope-normal) reservoir on [0, 20] m of a 30° incline, μ = 0.2, t = 2 s."""
    th = math.radians(MANG_THETA)
    h0 = MANG_HN / math.cos(th)
    eps = 1e-4 * MANG_LENGTH / cells
    return {
        "name": "mangeney_slope", "gravity": g,
        "domain": {"extent": [0, MANG_LENGTH, 0, 1], "cells": [cells, 2],
                   "boundary": {"left": "wall", "right": "open", "bottom": "wall", "top": "wall"}},
        "terrain": {"elevation": f"-{math.tan(th)!r} * x"},
        "initial": {"depth": f"where(x < {MANG_X0 - eps}, {h0!r}, "
                             f"where(x < {MANG_X0 + eps}, {h0 / 2!r}, 0))",
                    "velocity": ["0", "0"]},
        "material": {"density": 1000, "friction": {"law": "coulomb", "mu": MANG_MU}},
        "model": {"form": "slope"},
        "time": {"end": MANG_END, "cfl": 0.9}, "output": {"every": MANG_END},
    }
