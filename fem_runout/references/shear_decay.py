"""Viscous shear mode: decay of ``u = U cos(k y)`` under the Bingham viscosity (seed eq. 3).

With ``τ_Y = 0`` the Bingham stress of seed eq. 3 is Newtonian, ``σ = μ (∇v + ∇vᵀ)``, and the
depth-averaged momentum (seed eq. 1) carries ``∇·(h σ)/ρ``. A shear flow ``u(y, t)``, ``v = 0``,
on a flat bed with uniform depth has no pressure gradient and no advection (``u ∂x u = 0``),
so ``∂t u = (μ/ρ) ∂yy u`` and each Fourier mode decays exponentially::

    u(y, t) = U exp(-λ t) cos(k y),   λ = μ k²/ρ          (Stokes' first problem, Fourier mode)

Walls (slip) at ``y = 0`` and ``y = W`` with ``k = 2π/W`` satisfy ``∂y u = 0`` there.
"""

from __future__ import annotations

import math

W = 10.0
#: Length of the strip [m] and the window the rate is measured on. The open x-sides carry no
#: traction, which the exact shear flow does not satisfy; what they disturb travels at about
#: ``sqrt(g h)`` ≈ 3 m/s, with faster numerical precursors. On the former 40 m strip measured
#: on 10–30 m the depth in the window had moved by 1e-4 at 1 s, and the rate error at 80 cells
#: read 1.3e-4 where the shear mode's own error is 4.2e-4 (session 19). On 80 m, measured on
#: 30–50 m, the depth in the window stays within 1e-7 of its initial value.
LENGTH = 80.0
WINDOW = (30.0, 50.0)


def decay_rate(mu: float, rho: float, k: float = 2 * math.pi / W) -> float:
    """``λ = μ k²/ρ`` [1/s]."""
    return mu / rho * k * k


def case_dict(ny: int, mu: float = 500.0, tau: float = 0.0, end: float = 1.0,
              g: float = 9.81) -> dict:
    """Return the case: an 80 m × 10 m strip, slip walls at y = 0, 10 m, open x-sides.

    2 m cells along x; the rate is measured on :data:`WINDOW`.
    """
    return {
        "name": "shear", "gravity": g,
        "domain": {"extent": [0, LENGTH, 0, W], "cells": [int(LENGTH / 2), ny],
                   "boundary": {"left": "open", "right": "open", "bottom": "wall",
                                "top": "wall"}},
        "terrain": {"elevation": "0"},
        "initial": {"depth": "1", "velocity": [f"0.1*cos(2*pi*y/{W})", "0"]},
        "material": {"density": 1000, "rheology": {"law": "bingham", "viscosity": mu,
                                                   "yield_stress": tau}},
        "time": {"end": end, "cfl": 0.9}, "output": {"every": end},
    }


def measured_rate(x, y, h, hu, end: float, amplitude: float = 0.1, k: float = 2 * math.pi / W):
    """Decay rate fitted from the final state: projection of ``u`` on ``cos(k y)`` on the window."""
    import numpy as np

    inner = (x >= WINDOW[0]) & (x <= WINDOW[1])
    mode = np.cos(k * y[inner])
    amp = np.sum((hu / h)[inner] * mode) / np.sum(mode * mode)
    return -math.log(amp / amplitude) / end
