"""Stoker's wet-bed dam break (Stoker 1957): flat, frictionless, 1D.

Still water ``h_l`` on ``x <= x0`` and ``h_r > 0`` beyond, released at t = 0. The solution
is a rarefaction into the left state, a middle state ``(h_m, u_m)`` and a shock moving right
at speed ``s``. With ``c = sqrt(g h)``, ``h_m`` solves

    u_m = 2 (c_l - c_m) = (h_m - h_r) sqrt(g (h_m + h_r) / (2 h_m h_r))

(Riemann invariant across the rarefaction = Rankine–Hugoniot across the shock), and
``s = h_m u_m / (h_m - h_r)``. For ``x0 - c_l t < x < x0 + (u_m - c_m) t`` the fan gives
``h = (2 c_l - (x - x0)/t)² / (9 g)``, ``u = 2/3 ((x - x0)/t + c_l)``.
"""

from __future__ import annotations

import numpy as np

from fem_runout.methods import default_method


def stoker_middle(h_l: float, h_r: float, g: float) -> tuple[float, float, float]:
    """Middle depth ``h_m``, velocity ``u_m`` and shock speed ``s`` (bisection to round-off)."""
    if not 0.0 < h_r < h_l:
        raise ValueError("Stoker's dam break needs 0 < h_r < h_l")

    def gap(hm: float) -> float:
        return 2.0 * (np.sqrt(g * h_l) - np.sqrt(g * hm)) - (hm - h_r) * np.sqrt(
            g * (hm + h_r) / (2.0 * hm * h_r))

    lo, hi = h_r, h_l  # gap(lo) > 0 > gap(hi)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if gap(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    hm = 0.5 * (lo + hi)
    um = 2.0 * (np.sqrt(g * h_l) - np.sqrt(g * hm))
    return hm, um, hm * um / (hm - h_r)


def stoker_solution(x: np.ndarray, t: float, h_l: float, h_r: float, x0: float,
                    g: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact depth and velocity at positions ``x`` and time ``t > 0``."""
    hm, um, s = stoker_middle(h_l, h_r, g)
    cl, cm = np.sqrt(g * h_l), np.sqrt(g * hm)
    xi = (np.asarray(x, dtype=float) - x0) / t
    fan_h = (2.0 * cl - xi) ** 2 / (9.0 * g)
    fan_u = 2.0 / 3.0 * (xi + cl)
    h = np.where(xi <= -cl, h_l, np.where(xi <= um - cm, fan_h, np.where(xi < s, hm, h_r)))
    u = np.where(xi <= -cl, 0.0, np.where(xi <= um - cm, fan_u, np.where(xi < s, um, 0.0)))
    return h, u


def dam_break_case(h_l: float, h_r: float, x0: float, cells: tuple[int, int], end: float,
                   method: str | None = None) -> dict:
    """Case of a 1D dam break on the flat strip [0, 100] × [0, 2] m (``h_r = 0``: Ritter).

    Walls along the flow, open ends. The node on the dam carries the mean of the two depths,
    so the Q1 interpolant holds the exact volume when ``x0`` is a node. ``method`` defaults to
    the registry's default method (:func:`fem_runout.methods.default_method`).
    """
    method = method or default_method()
    mid = 0.5 * (h_l + h_r)
    return {
        "name": "dam_break_1d", "method": method, "gravity": 9.81,
        "domain": {"extent": [0, 100, 0, 2], "cells": list(cells),
                   "boundary": {"left": "open", "right": "open", "bottom": "wall",
                                "top": "wall"}},
        "terrain": {"elevation": "0"},
        "initial": {"depth": f"where(x < {x0} - 1e-6, {h_l}, where(x < {x0} + 1e-6, {mid}, "
                             f"{h_r}))", "velocity": ["0", "0"]},
        "material": {"density": 1000, "friction": {"law": "none"},
                     "rheology": {"law": "none"}},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    }


def exact_depth(x: np.ndarray, t: float, h_l: float, h_r: float, x0: float,
                g: float) -> np.ndarray:
    """Stoker's depth, or Ritter's when ``h_r = 0``."""
    if h_r == 0.0:
        from fem_runout.references.ritter import ritter_depth

        return ritter_depth(x, t, h_l, x0, g)
    return stoker_solution(x, t, h_l, h_r, x0, g)[0]
