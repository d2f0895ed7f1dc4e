"""Per-step envelopes of the flow (peak depth, speed, pressure, arrival) in one compiled pass.

The hazard maps and the peak tracker fold the state into their maxima after every step, on
the flow's owned nodes (the state is zero elsewhere). As NumPy formulas that took a dozen
gathers, masks and scatters per step, replicated on every rank; this pass gives the same
bits (:func:`fem_runout.output.diagnostics.nodal_speed`'s speed, ``np.maximum``'s choice on
ties and NaN).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["fold_envelopes"]


@numba.njit(cache=True, inline="always")
def _maximum(a, b):
    """``np.maximum(a, b)`` on scalars: NaN wins, ``b`` on ties (signed zeros included)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


@numba.njit(cache=True)
def _fold(nodes, h, hu, hv, threshold, t, density, depth, speed, pressure, arrival):
    track = pressure.size > 0
    for k in range(nodes.size):
        i = nodes[k]
        hi = h[i]
        wet = hi > threshold
        v = math.hypot(hu[i], hv[i]) / hi if wet else 0.0
        depth[i] = _maximum(depth[i], hi)
        speed[i] = _maximum(speed[i], v)
        if track:
            pressure[i] = _maximum(pressure[i], density * (v * v))
            if wet and arrival[i] != arrival[i]:
                arrival[i] = t


def fold_envelopes(nodes: np.ndarray, h: np.ndarray, hu: np.ndarray, hv: np.ndarray,
                   threshold: float, depth: np.ndarray, speed: np.ndarray,
                   pressure: np.ndarray | None = None, arrival: np.ndarray | None = None,
                   t: float = 0.0, density: float = 0.0) -> None:
    """Fold the state at ``nodes`` into the envelopes, in place.

    ``depth = max(depth, h)``, ``speed = max(speed, |q|/h)`` (0 where ``h <= threshold``);
    with ``pressure`` and ``arrival`` also ``pressure = max(pressure, ρ v²)`` and the arrival
    time ``t`` where it is still NaN and ``h > threshold``.

    Args:
        nodes: Local node indices (the flow's owned nodes).
        h: Nodal depth (every local node).
        hu: Nodal x-momentum.
        hv: Nodal y-momentum.
        threshold: Depth above which a node is wet [m].
        depth: Peak depth per local node, updated.
        speed: Peak speed per local node, updated.
        pressure: Peak pressure ``ρ v²`` per local node, updated (or None).
        arrival: First arrival time per local node (NaN: not yet), updated (or None).
        t: Time of the state [s].
        density: ``ρ`` [kg/m³].
    """
    none = np.zeros(0)
    _fold(np.asarray(nodes, dtype=np.int64), h, hu, hv, float(threshold), float(t),
          float(density), depth, speed, none if pressure is None else pressure,
          none if arrival is None else arrival)
