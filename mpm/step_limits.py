"""DAMPM's stable step: the particles' transport limit, the slope's and the viscous one.

A step is at most ``COURANT`` times the time the fastest particle (speed plus wave speed)
takes to cross a cell, at most the slope-acceleration limit of
:func:`fem_runout.stepping.acceleration_limit`, and with a Bingham viscosity at most
``VISCOUS`` times the explicit viscous limit. Each rank computes its part
(:func:`local_limits`); one max reduction over the ranks (the solver's health check carries
it) gives the values :func:`limits_from` turns into the step.
"""

from __future__ import annotations

import numpy as np

from fem_runout.stepping import acceleration_limit

__all__ = ["COURANT", "VISCOUS", "crossing_time", "limits_from", "local_limits"]

#: Fraction of the cell crossing time ``Δx / max(|v_p| + sqrt(g h_p))`` given as the stable step.
COURANT = 0.5
#: Fraction of the explicit viscous limit ``ρ Δx² / (8 μ)`` of the Newtonian part.
VISCOUS = 0.5


def crossing_time(p, grid, gp: np.ndarray, g: float, basis) -> float:
    """``min_p s_p / (|v_p| + sqrt(max(G_p, g) h_p))``, ``s_p`` the size of the cells it reaches.

    ``basis``: the particles' weights (:meth:`mpm.mesh_grid.MeshParticleGrid.crossing_sizes`).
    """
    speed = np.sqrt(p.u * p.u + p.v * p.v) + np.sqrt(np.maximum(gp, g) * p.h)
    size = grid.crossing_sizes(p, basis)
    ok = speed > 0.0
    return float(np.min(size[ok] / speed[ok], initial=np.inf))


def local_limits(p, grid, speed: float, slope: float, gp: np.ndarray, g: float, basis
                 ) -> np.ndarray:
    """Return this rank's ``[top speed, steepest slope]``, to maximise over the ranks.

    On the structured grid the top speed of the particles (:func:`mpm.forces.particle_forces`
    gives it); with cells of many sizes minus each particle's own crossing time (a max
    reduction then gives the minimum; negation is exact), from the particles' weights
    ``basis`` (:func:`crossing_time`).
    """
    first = speed if grid.structured else -crossing_time(p, grid, gp, g, basis)
    return np.array([first, slope], dtype=float)


def limits_from(both: np.ndarray, grid, g: float, rho: float, viscosity: float
                ) -> tuple[float, float]:
    """``(stable step, transport step)`` from the ranks' maxima of :func:`local_limits`.

    Args:
        both: The reduced ``[top speed (or minus the crossing time), steepest slope]``.
        grid: The particle grid (its smallest cell size ``Δx``).
        g: Gravity [m/s²].
        rho: Density [kg/m³].
        viscosity: The Bingham viscosity ``μ`` [Pa s] (0: none).
    """
    dx = grid.min_size
    top, slope = float(both[0]), float(both[1])
    if grid.structured:
        dt = COURANT * dx / top if top > 0 else np.inf
    else:
        dt = COURANT * -top
    dt = min(dt, acceleration_limit(dx, g, slope))
    transport = dt
    if viscosity > 0.0:  # the yield stress is bounded (|σ_Y| <= τ_Y): only μ limits the step
        dt = min(dt, VISCOUS * rho * dx * dx / (8.0 * viscosity))
    return dt, transport
