"""DAMPM's particle update from the velocity gradient: depth (seed eq. 42), stress (eqs. 40-41).

Given the velocity gradient ``L_p`` at the particles (MUSL, :mod:`mpm.solver`), the strain
increment is ``Δε_p = Δt sym(L_p)`` (eq. 40), the column depth follows the area change,
``h_p ← h_p / (1 + Δt tr L_p)`` (eq. 42), and with a Bingham rheology the stress is
``σ_p = 2 μ_eff D_p`` with ``D_p = sym(L_p)`` (eqs. 3 and 41; USL: updated last).
"""

from __future__ import annotations

import numpy as np

from fem_runout.physics.rheology import Bingham
from mpm.particles import Particles

__all__ = ["update_depth_and_stress"]


def update_depth_and_stress(p: Particles, dt: float, grad: np.ndarray,
                            rheology: Bingham | None, grid_depth: np.ndarray | None = None,
                            depth_cap: float | None = None) -> str | None:
    """Update the particles' depth (eq. 42) and stress (eqs. 40-41) in place.

    With ``grid_depth`` (the depth the particle volumes make on the grid at the particles)
    the depth entering eq. 42 is first capped, ``h_p ← min(h_p, κ h̄_p)`` with ``κ`` =
    ``depth_cap``: where particles pile up, eq. 42's Lagrangian depths drift far above the
    grid's (docs/dampm.md, "Depth cap").

    Args:
        p: The particles (``h`` and the stresses are replaced).
        dt: Step [s].
        grad: (n, 2, 2) velocity gradient ``L_p``.
        rheology: The Bingham rheology, or None (no stress).
        grid_depth: ``h̄_p`` at the particles, or None (eq. 42 alone).
        depth_cap: ``κ`` (used with ``grid_depth``).

    Returns:
        None, or a message if a column was squeezed past zero within the step (``1 + Δt tr
        L_p <= 0``); the depths are then left as they were after the cap.
    """
    if grid_depth is not None:
        p.h = np.minimum(p.h, depth_cap * grid_depth)
    factor = 1.0 + dt * (grad[:, 0, 0] + grad[:, 1, 1])
    if not (factor > 0.0).all():  # squeezed past zero in one step: stop, state kept
        worst = int(np.argmin(factor))
        return (f"a particle column collapsed (1 + dt div v = {factor[worst]:.3g} "
                f"<= 0, seed eq. 42) at particle {int(p.id[worst])}")
    p.h = p.h / factor  # eq. 42
    if rheology is None:
        return None
    mu = rheology.effective_viscosity(p.h, p.u, p.v, grad)
    d = 0.5 * (grad + np.swapaxes(grad, 1, 2))
    p.sxx, p.syy, p.sxy = 2.0 * mu * d[:, 0, 0], 2.0 * mu * d[:, 1, 1], 2.0 * mu * d[:, 0, 1]
    return None
