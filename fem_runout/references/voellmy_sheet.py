"""Voellmy sheet: a uniform layer sliding down a uniform slope (seed eq. 2).

On the plane ``Z = -S x`` (horizontal coordinates, seed eq. 1) a layer of uniform depth ``h``
and velocity ``u(t)`` has no pressure or depth gradient, so the momentum balance reduces to an
ODE with the friction of seed eq. 2 (normal stress ``ρ g h``, see ``physics/friction/``)::

    du/dt = g (S - μ) - g u²/(ξ h) = a - b u²,   a = g (S - μ),  b = g/(ξ h)
    u(t) = sqrt(a/b) tanh(sqrt(a b) t)             (u(0) = 0, S > μ)

Terminal speed ``u_∞ = sqrt(a/b) = sqrt(ξ h (S - μ))`` (Voellmy 1955; Salm 1993).
"""

from __future__ import annotations

import math


def speed(t: float, slope: float, mu: float, xi: float, h: float, g: float = 9.81) -> float:
    """Exact sheet speed [m/s] at time ``t`` from rest."""
    a, b = g * (slope - mu), g / (xi * h)
    return math.sqrt(a / b) * math.tanh(math.sqrt(a * b) * t)


def terminal_speed(slope: float, mu: float, xi: float, h: float) -> float:
    """``u_∞ = sqrt(ξ h (S - μ))`` [m/s] (independent of g)."""
    return math.sqrt(xi * h * (slope - mu))


def relaxation_time(slope: float, mu: float, xi: float, h: float, g: float = 9.81) -> float:
    """``1/sqrt(a b)`` [s]: after 3 of these ``u`` is within 1 % of ``u_∞``."""
    return 1.0 / math.sqrt(g * (slope - mu) * g / (xi * h))


def strip_case(name: str, cells: int, length: float, elevation: str, depth: str,
               friction: dict, end: float, g: float = 9.81, form: str | None = None) -> dict:
    """Return a sheet case: a ``length`` × 4 m strip on ``cells`` × 2 cells, at rest at t = 0.

    Wall upstream and on the sides, open downstream; density 1200 kg/m³, CFL 0.9, one output at
    ``end``; ``form`` sets ``model.form`` (None: the default, horizontal without a DEM).
    """
    case = {
        "name": name, "gravity": g,
        "domain": {"extent": [0, length, 0, 4], "cells": [cells, 2],
                   "boundary": {"left": "wall", "right": "open", "bottom": "wall",
                                "top": "wall"}},
        "terrain": {"elevation": elevation},
        "initial": {"depth": depth, "velocity": ["0", "0"]},
        "material": {"density": 1200, "friction": friction},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    }
    if form is not None:
        case["model"] = {"form": form}
    return case


def case_dict(cells: int, slope: float = 0.3, mu: float = 0.1, xi: float = 500.0,
              h: float = 1.0, end: float | None = None, g: float = 9.81) -> dict:
    """Return the case: a 400 m × 4 m strip (wall upstream and on the sides, open downstream).

    Boundary disturbances travel at most at ``|u| + sqrt(g h)`` (< 15 m/s here), so the window
    [250, 350] m keeps the uniform layer of the exact solution for ``end`` <= 3 relaxation times.
    """
    end = 3.0 * relaxation_time(slope, mu, xi, h, g) if end is None else end
    return strip_case("voellmy_sheet", cells, 400.0, f"-{slope} * x", str(h),
                      {"law": "voellmy", "mu": mu, "xi": xi}, end, g)


WINDOW = (250.0, 350.0)
