"""Bounds of the transport step that come from the physics rather than the CFL condition.

* :func:`bound_speed`: a node's speed may not exceed what its deeper neighbours can feed it
  (Riemann invariant of a rarefaction plus the fall down the bed), so drying layers drain.
* :func:`node_slopes`: the bed slope per node, for the time-step limit from the slope
  acceleration (:meth:`.transport.Transport.stable_dt`).
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.mesh import Discretization, GhostReducer

__all__ = ["SPEED_MARGIN", "bound_speed", "deeper_patch_max", "node_slopes", "patch_speed_max"]

#: Allowed overshoot of the speed bound, in local wave speeds sqrt(g h) (see bound_speed).
SPEED_MARGIN = 0.35


@numba.njit(cache=True)
def deeper_patch_max(cells, speed, depth, z, g, gn, vmax):
    """Speed bound from the patch: Riemann invariant plus the drop in bed, deeper nodes weighted.

    For every other node ``j`` of i's cells, ``vmax[i]`` is extended by
    ``ρ_ij (sqrt((|u_j| + 2 c_j)² + 2 g max(Z_j - Z_i, 0)) - 2 c_i)`` (``c = sqrt(g h)``): the
    speed a flow from ``j`` can reach at ``i`` by expanding into shallower water (``u + 2c``
    is constant across a rarefaction) and falling down the bed. The weight
    ``ρ_ij = clip(2 h_j / h_i - 1, 0, 1)`` is 1 where j is at least as deep as i, 0 where it
    is less than half as deep and linear in between, so that thin fast nodes do not feed
    each other's bounds, without a switch on ``h_j >= h_i``. A node with no neighbour at
    least half as deep gets 0 here (then only the margin ``SPEED_MARGIN c_i``). The wave
    speeds use the nodal gravity ``gn`` of the pressure term (``g``, or the slope form's
    ``G``); the fall uses ``g`` (an upper bound of the energy it gives).
    """
    n = depth.shape[0]
    wave = np.empty(n)  # c = sqrt(g h) per node, once
    for i in range(n):
        wave[i] = np.sqrt(gn[i] * max(depth[i], 0.0))
    for k in range(cells.shape[0]):
        for a in range(4):
            i = cells[k, a]
            hi = max(depth[i], 0.0)
            ci = wave[i]
            for b in range(4):
                if b == a:
                    continue
                j = cells[k, b]
                hj = max(depth[j], 0.0)
                if hj >= hi:
                    rho = 1.0
                else:
                    rho = max(0.0, 2.0 * hj / hi - 1.0)  # hi > hj >= 0 here
                r = speed[j] + 2.0 * wave[j]
                drop = max(z[j] - z[i], 0.0)
                # sqrt(r²) = r exactly in binary floating point: skip it where the bed is flat
                reach = np.sqrt(r * r + 2.0 * g * drop) if drop > 0.0 else r
                vmax[i] = max(vmax[i], rho * max(reach - 2.0 * ci, 0.0))


def patch_speed_max(cells: np.ndarray, q_low: np.ndarray, z: np.ndarray, g: float,
                    speed: np.ndarray, gn: np.ndarray) -> np.ndarray:
    """Return this rank's part of the patch speed bound of :func:`bound_speed`.

    :func:`deeper_patch_max` over the local cells. The caller reduces it (max) over the
    ranks sharing a node before :func:`bound_speed`;
    the transport does so in the limiter's exchange of its bounds.

    Args:
        cells: (n_cells_local, 4) local nodes of every local cell.
        q_low: (n, 3) low-order state ``h, hu, hv``.
        z: Nodal bed elevation.
        g: Gravity [m/s²].
        speed: (n,) desingularised low-order speed.
        gn: (n,) nodal gravity of the wave speeds.
    """
    smax = np.zeros(q_low.shape[0])
    deeper_patch_max(cells, np.ascontiguousarray(speed), np.ascontiguousarray(q_low[:, 0]), z,
                     g, gn, smax)
    return smax


def bound_speed(q_low: np.ndarray, q: np.ndarray, smax: np.ndarray, gn: np.ndarray) -> None:
    """Bound each node's speed by what its patch can feed it (continuous in the data).

    The limiter bounds the momenta, not the velocity; in a draining layer (h → 0) the
    momentum antidiffusion can leave ``|q| / h`` far above any neighbour's speed. The bound
    at node ``i`` is ``max_j ρ_ij [sqrt((|u_j| + 2 c_j)² + 2 g max(Z_j - Z_i, 0)) - 2 c_i]
    + SPEED_MARGIN c_i`` over the nodes ``j`` of its patch (:func:`patch_speed_max`,
    low-order state, ``c = sqrt(g h)``), plus a margin of ``SPEED_MARGIN`` local wave speeds
    for smooth high-order overshoots. Where the speed is above, the momentum is scaled back
    to the bound, direction kept: ``q ← q min(1, h s_max / |q|)``, a Lipschitz map. The
    margin is applied at every step and so can ratchet a jet up: with 1.5 (issue 5's value)
    a flow falling over a 30 m drop (cases/hard/drop.yaml) reached 50 m/s on the flat floor,
    free fall plus the release's wave speed being 37.6 m/s; 0.25 gave 37.2 m/s. Ritter's
    error needs a margin (0.188 at 400 cells with none, 0.113 with 0.25 or more). 0.35 (session
    17) lets the inclined dam-break tip keep up (front error at 900 cells 0.0524 → 0.0499)
    with every 1e-14 continuity change below 2.3e-11; 0.5 raised the Coulomb pit's to 1.3e-9.

    History, measured on the hard cases of issue 5: a bound of 1.5 × the patch maximum of
    all low-order speeds (the node's own included) let a drying rim node on a slope keep
    its momentum while its depth drained (81 m/s after 0.84 s in "pit", bound 20 m/s); a
    multiplicative margin on the deeper neighbours compounded along chains of decreasing
    depth (70 m/s in the splash below the 20 m "cliff", bound 57 m/s). Issue 13: the
    switches "neighbour at least as deep", "wet" and "no deeper neighbour" are replaced by
    the continuous weight ρ, so a 1e-15 change of a depth no longer moves the bound by O(1).

    Args:
        q_low: (n, 3) low-order state ``h, hu, hv``.
        q: (n, 3) new state, momenta scaled in place.
        smax: (n,) :func:`patch_speed_max` reduced over the ranks.
        gn: (n,) nodal gravity of the wave speeds (``g``, or the slope form's ``G``).
    """
    _scale_speed(q_low, q, smax, gn, SPEED_MARGIN)


@numba.njit(cache=True)
def _scale_speed(q_low, q, smax, gn, margin):
    """Scale the momenta of ``q`` down to the speed bound (the loop of :func:`bound_speed`)."""
    for i in range(q.shape[0]):
        norm = np.hypot(q[i, 1], q[i, 2])
        wave = np.sqrt(gn[i] * max(q_low[i, 0], 0.0))
        limit = max(q[i, 0], 0.0) * (smax[i] + margin * wave)
        if norm > limit:
            r = limit / norm
            q[i, 1] *= r
            q[i, 2] *= r


@numba.njit(cache=True)
def low_order_speed(q, kappa, out):
    """Write ``|u_i|`` of the rows ``(h, hu, hv)`` of ``q`` into ``out``.

    Desingularised as :func:`fem_runout.tg2.low_order.velocity` (the same operations).
    """
    for i in range(q.shape[0]):
        hp = max(q[i, 0], 0.0)
        hk = max(q[i, 0], kappa)
        f = 2.0 * hp / (hp * hp + hk * hk)
        out[i] = np.hypot(q[i, 1] * f, q[i, 2] * f)


def node_slopes(disc: Discretization, z: np.ndarray, reducer: GhostReducer) -> np.ndarray:
    """Steepest cell-mean bed slope ``|∇Z|`` around every node (local nodes, ranks reduced)."""
    grad = np.einsum("cija,cj->ca", disc.C, z[disc.cell_nodes]) / disc.cell_area[:, None]
    slope = np.zeros(disc.coords.shape[0])
    np.maximum.at(slope, disc.cell_nodes.ravel(), np.repeat(np.hypot(*grad.T), 4))
    reducer.reduce(slope, "max")
    return slope
