"""Discrete norms on the gathered node arrays of a structured run (sorted by (y, x))."""

from __future__ import annotations

import numpy as np


def nodal_weights(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Lumped Q1 mass of each node of a uniform rectangular grid (exact ``∫ φ_i``).

    Args:
        x: Node x-coordinates of the whole grid.
        y: Node y-coordinates of the whole grid.
    """
    def weights_1d(v: np.ndarray) -> np.ndarray:
        u = np.unique(np.round(v, 9))
        dv = np.diff(u)
        w = np.zeros_like(u)
        w[:-1] += 0.5 * dv
        w[1:] += 0.5 * dv
        return w[np.searchsorted(u, np.round(v, 9))]

    return weights_1d(x) * weights_1d(y)


def l1(values: np.ndarray, weights: np.ndarray) -> float:
    """``Σ_i m_i |v_i|`` (the L1 norm over the domain, lumped quadrature)."""
    return float(np.sum(weights * np.abs(values)))


def linf(values: np.ndarray) -> float:
    """``max_i |v_i|``."""
    return float(np.max(np.abs(values))) if values.size else 0.0


def front_radius(x, y, h, center, threshold, direction) -> float:
    """Distance from ``center`` along a ray to where ``h`` falls to ``threshold``.

    The nodes on the ray (within 1e-6 of it, ``along >= 0``) are sorted by distance; past the
    last node with ``h > threshold`` the crossing is interpolated linearly towards the next
    node. The radius is continuous in the data (a node's depth passing the threshold moves it
    by round-off, not by a cell), so sub-cell differences between directions show.

    Args:
        x: Gathered node x-coordinates.
        y: Gathered node y-coordinates.
        h: Gathered depth.
        center: (xc, yc), a node of the grid.
        threshold: Wet threshold [m].
        direction: Unit vector.
    """
    dx, dy = x - center[0], y - center[1]
    along = dx * direction[0] + dy * direction[1]
    across = np.abs(dx * direction[1] - dy * direction[0])
    ray = (across < 1e-6) & (along >= 0)
    order = np.argsort(along[ray], kind="stable")
    return crossing(along[ray][order], h[ray][order], threshold)


def crossing(dist: np.ndarray, depth: np.ndarray, threshold: float) -> float:
    """Where ``depth`` (at increasing ``dist``) falls to ``threshold`` for the last time.

    Past the last sample with ``depth > threshold`` the crossing is interpolated linearly
    towards the next sample (the last sample's distance if there is none; 0 if all are dry).
    """
    wet = np.flatnonzero(depth > threshold)
    if wet.size == 0:
        return 0.0
    k = int(wet[-1])
    if k + 1 == dist.size:
        return float(dist[k])
    share = (depth[k] - threshold) / (depth[k] - depth[k + 1])
    return float(dist[k] + share * (dist[k + 1] - dist[k]))
