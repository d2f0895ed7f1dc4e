"""Both SDIRK stages of ``FrictionLaw.integrate``, compiled: one pass over the nodes.

The step's friction is two implicit stage solves per node (Alexander's SDIRK; see "Over a whole
step" in :mod:`fem_runout.physics.friction.base`). As numpy passes over the few thousand nodes
a flow wets, the yield test, the bed's gravity scales and the stage coupling cost about 1 ms
per step in calls (about 80 passes), the same on one rank as on two. This kernel does the same
operations in the same order on each node as :meth:`FrictionLaw.implicit_update` and
:meth:`FrictionLaw.integrate`, so the results are the same bits (tested); the law still says
its own drag coefficient ``k`` (computed once per step: ``h`` and the bed are frozen).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fem_runout.physics.friction.newton import newton_direction

__all__ = ["integrate_nodes"]


@numba.njit(cache=True, inline="always")
def _stage(h, dry, qx, qy, sx, sy, theta, mu, g, k, gx, gy, cos, normal, on_bed, rtol,
           max_iter):
    """One :meth:`FrictionLaw.implicit_update` on one node: ``(q_x, q_y, failed)``."""
    if not h > dry:
        return 0.0, 0.0, 0
    norm = math.hypot(sx, sy)
    unit = norm if norm > 0.0 else 1.0
    gc, gt = g, g
    if on_bed:
        along = sx / unit * gx + sy / unit * gy
        s = math.sqrt(1.0 + along * along)
        gc, gt = normal / s, g * s / cos
    moving = norm > theta * gc * mu * h
    safe = norm if moving else 1.0
    nx = sx / safe if moving else 0.0
    ny = sy / safe if moving else 0.0
    ox, fx = newton_direction(h, sx, qx, nx, moving, gc, gt, k, theta, mu, rtol, max_iter)
    oy, fy = newton_direction(h, sy, qy, ny, moving, gc, gt, k, theta, mu, rtol, max_iter)
    return ox, oy, fx + fy


@numba.njit(cache=True)
def _integrate(h, qx, qy, dt, gamma, mu, g, dry, k, grad, cos, normal, on_bed, rtol, max_iter,
               out_x, out_y):
    failed = 0
    c = (1.0 - gamma) / gamma
    theta = gamma * dt
    for i in range(h.size):
        gx = grad[i, 0] if on_bed else 0.0
        gy = grad[i, 1] if on_bed else 0.0
        ci = cos[i] if on_bed else 1.0
        ni = normal[i] if on_bed else 0.0
        ax, ay, f1 = _stage(h[i], dry, qx[i], qy[i], qx[i], qy[i], theta, mu, g, k[i], gx, gy,
                            ci, ni, on_bed, rtol, max_iter)
        norm = math.hypot(qx[i], qy[i])
        ratio = math.hypot(ax, ay) / (norm if norm > 0.0 else 1.0)
        f = 1.0 + c * (ratio - 1.0)
        f = f if (f > 0.0 or f != f) else 0.0  # np.maximum(f, 0): NaN stays NaN
        bx, by, f2 = _stage(h[i], dry, ax, ay, f * qx[i], f * qy[i], theta, mu, g, k[i], gx, gy,
                            ci, ni, on_bed, rtol, max_iter)
        out_x[i], out_y[i] = bx, by
        failed += f1 + f2
    return failed


def integrate_nodes(h: np.ndarray, qx: np.ndarray, qy: np.ndarray, dt: float, gamma: float,
                    mu: float, gravity: float, dry_tol: float, k, bed, rtol: float,
                    max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Two-stage SDIRK friction step on every node (see the module docstring).

    Args:
        h: Depth [m] (frozen), shape (n,).
        qx: x-momentum at the start [m²/s].
        qy: y-momentum at the start [m²/s].
        dt: Step [s].
        gamma: ``γ_s`` of the SDIRK.
        mu: Coulomb coefficient.
        gravity: ``g`` [m/s²].
        dry_tol: Nodes with ``h <= dry_tol`` are dry (zero momentum).
        k: The law's drag coefficient, scalar or per node (with the depth 1 where dry).
        bed: A :class:`fem_runout.physics.slope.BedFrame`, or None (the seed's form).
        rtol: Newton's relative tolerance.
        max_iter: Newton's iteration bound per node.

    Returns:
        ``(qx, qy)`` after ``dt``.

    Raises:
        FloatingPointError: If Newton does not converge on some node.
    """
    n = h.size
    f64 = [np.ascontiguousarray(a, dtype=np.float64) for a in (h, qx, qy)]
    kk = np.ascontiguousarray(np.broadcast_to(np.asarray(k, dtype=np.float64), (n,)))
    if bed is None:
        grad, cos, normal, on_bed = np.zeros((1, 2)), np.zeros(1), np.zeros(1), False
    else:
        grad = np.ascontiguousarray(bed.grad, dtype=np.float64)
        cos = np.ascontiguousarray(bed.cos, dtype=np.float64)
        normal = np.ascontiguousarray(np.broadcast_to(np.asarray(bed.normal, np.float64), (n,)))
        on_bed = True
    out_x, out_y = np.empty(n), np.empty(n)
    failed = _integrate(*f64, float(dt), float(gamma), float(mu), float(gravity),
                        float(dry_tol), kk, grad, cos, normal, on_bed, float(rtol),
                        int(max_iter), out_x, out_y)
    if failed:
        raise FloatingPointError("friction Newton iteration did not converge")
    return out_x, out_y
