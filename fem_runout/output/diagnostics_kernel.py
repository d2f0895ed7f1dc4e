"""The series' per-step diagnostics in two compiled passes over the flow's nodes.

:func:`fem_runout.output.diagnostics.compute_diagnostics` runs every step of every run. Its
NumPy form gathered the flow's nodes into five arrays, masked them, built three term arrays
and reduced each: about 40 array operations, 0.3 ms a step whatever the flow's size (a fifth
of a small case's step). Here the first pass gives this rank's maxima, the second the two
folds of each exact sum (:mod:`fem_runout.exact_sum`) with the extractors of the maxima
reduced over the ranks. Every term is formed with the same operations in the same order as
the NumPy form, and the folds' partial sums are exact in any order, so the totals and maxima
have the same bits (tested against the NumPy form).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from fem_runout.exact_fold import fold

__all__ = ["diagnostic_folds", "diagnostic_maxima"]


@numba.njit(cache=True)
def diagnostic_maxima(idx, x, mass, h, hu, hv, threshold, density, owned):
    """Return the rank's maxima of ``|m h|``, ``|ρ/2 m |q|²/h|``, ``m``, ``h``, speed, ``x``.

    The second, third, fifth and sixth over the wet nodes.

    Args:
        idx: The flow's owned dofs.
        x: x of the owned dofs (all of them, indexed by ``idx``).
        mass: Lumped mass on the dofs.
        h: Depth on the dofs.
        hu: x discharge on the dofs.
        hv: y discharge on the dofs.
        threshold: Nodes with ``h > threshold`` are wet.
        density: ρ.
        owned: This rank owns dofs (else the depth's maximum is ``-inf``).

    Returns:
        (6,) the first three are 0 without terms, the depth's 0 (or ``-inf``), the speed's 0,
        the front's ``-inf`` without wet nodes.
    """
    c = 0.5 * density
    t0 = t1 = t2 = h_top = speed = 0.0
    front = -math.inf
    nan = np.zeros(6, dtype=np.bool_)  # NumPy's max: a NaN wins
    for a in idx:
        m, d = mass[a], h[a]
        v = abs(m * d)
        if v > t0:
            t0 = v
        elif v != v:
            nan[0] = True
        if d > h_top:
            h_top = d
        elif d != d:
            nan[3] = True
        if d > threshold:
            q2 = hu[a] * hu[a] + hv[a] * hv[a]
            v = abs(c * (m * q2 / d))
            if v > t1:
                t1 = v
            elif v != v:
                nan[1] = True
            if abs(m) > t2:
                t2 = abs(m)
            elif m != m:
                nan[2] = True
            v = math.sqrt(q2) / d
            if v > speed:
                speed = v
            elif v != v:
                nan[4] = True
            front = max(front, x[a])
    out = np.array([t0, t1, t2, h_top if owned else -math.inf, speed, front])
    for k in range(6):
        if nan[k]:
            out[k] = math.nan
    return out


@numba.njit(cache=True)
def diagnostic_folds(idx, mass, h, hu, hv, threshold, density, ext):
    """Return the two folds of the exact sums of ``m h``, ``ρ/2 m |q|²/h`` and wet ``m``, (6,).

    ``ext``: (3, 2) extractors (:func:`fem_runout.exact_sum.fold_extractors`).
    """
    c = 0.5 * density
    e0, e1, e2 = ext[0, 0], ext[1, 0], ext[2, 0]
    f0, f1, f2 = ext[0, 1], ext[1, 1], ext[2, 1]
    hi0 = lo0 = hi1 = lo1 = hi2 = lo2 = 0.0
    for a in idx:
        m, d = mass[a], h[a]
        hi, lo = fold(m * d, e0, f0)
        hi0 += hi
        lo0 += lo
        if d > threshold:
            q2 = hu[a] * hu[a] + hv[a] * hv[a]
            hi, lo = fold(c * (m * q2 / d), e1, f1)
            hi1 += hi
            lo1 += lo
            hi, lo = fold(m, e2, f2)
            hi2 += hi
            lo2 += lo
    return np.array([hi0, lo0, hi1, lo1, hi2, lo2])
