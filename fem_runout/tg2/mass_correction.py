"""Consistent-mass correction of the TG2-PC corrector, gated by a smoothness sensor.

The seed's corrector (eq. 15) divides by the lumped mass, ``ΔQ^H = M_L⁻¹ R^H``. Lumping
costs the Galerkin step its phase accuracy. One defect-correction (Jacobi) sweep towards
the consistent mass restores most of it (Löhner et al. 1987; Kuzmin & Turek 2002, FEM-FCT):

    M_L ΔQ ≈ R^H + (M_L − M_C) ΔQ^H,   element contributions  c_K = (M_L^K − M_C^K) ΔQ^H.

Each ``c_K`` sums to zero over its cell (``M_C^K`` is symmetric and its row sums are
``M_L^K``), so mass is conserved. It vanishes on a lake at rest (``ΔQ^H = 0``). It is added
to the antidiffusive contributions, so the limiter bounds it like the rest of the correction.

**Gate.** At fronts, shocks and extrema the correction steepens what the low-order scheme
smooths, and that costs accuracy there. Ungated: Ritter +26–38 %, Mangeney's incline
+30–105 %, Stoker's downstream level dips (docs/limiter.md, sessions 18–19). So each cell's
``c_K`` is weighted by

    w_K = min_{a ∈ K} (1 − s_a),   s_i = |Σ_j (h_j − h_i)| / (Σ_j |h_j − h_i| + δ),

Jameson's sensor, summed over the node pairs of every cell around ``i``:

- ``s = 0`` on linear data and ``s = 1`` at a local extremum or a dry front;
- ``δ = 1e3 κ`` (the thin-layer depth) keeps ``s`` Lipschitz where the depth is uniform.

``w_K`` is continuous in the data, so the step stays continuous (no switch).

Measured against the same scheme without it (1 rank; docs/limiter.md, session 19):
hemisphere L1 6–30 % lower, Thacker's bowl 2–13 % lower, the inclined dam break −13 % to
+8 %, Ritter and Stoker −5 % to +10 %, Mangeney's incline +6 to +21 % (still 0.55–0.74 of
its error before issue 13).
"""

from __future__ import annotations

import numba
import numpy as np

from fem_runout.active import ActiveSet
from fem_runout.mesh import Discretization, element_masses

__all__ = ["MassCorrection"]

#: Regularisation of the sensor's denominator, in units of κ.
SENSOR_DEPTH = 1e3


@numba.njit(cache=True)
def sensor_sums(cells, h, high, out):
    """``out[K, a, 3] = Σ_b (h_b − h_a)``, ``out[K, a, 4] = Σ_b |h_b − h_a|`` over the cell.

    ``out[K, a, :3]`` gets ``high[K, a]`` (the contributions summed in the same exchange).
    """
    for k in range(cells.shape[0]):
        for a in range(4):
            out[k, a, 0], out[k, a, 1], out[k, a, 2] = high[k, a, 0], high[k, a, 1], high[k, a, 2]
            ha = h[cells[k, a]]
            s1 = 0.0
            s2 = 0.0
            for b in range(4):
                d = h[cells[k, b]] - ha
                s1 += d
                s2 += abs(d)
            out[k, a, 3] = s1
            out[k, a, 4] = s2


@numba.njit(cache=True)
def rates_and_sensor(sums, boundary, mass, delta, dq, sensor):
    """``dq = (sums[:, :3] + boundary) / mass``, ``sensor = |sums[:, 3]| / (sums[:, 4] + δ)``.

    The high-order rate ``ΔQ^H`` of each node and the smoothness sensor ``s`` of the depth.
    """
    for i in range(sums.shape[0]):
        for c in range(3):
            dq[i, c] = (sums[i, c] + boundary[i, c]) / mass[i]
        sensor[i] = abs(sums[i, 3]) / (sums[i, 4] + delta)


@numba.njit(cache=True)
def add_correction(cells, mc, dq, sensor, aec):
    """``aec[K] += w_K (M_L^K − M_C^K) ΔQ^H`` with ``w_K = min_a (1 − s_a)`` (in place)."""
    for k in range(cells.shape[0]):
        w = 1.0
        for a in range(4):
            w = min(w, 1.0 - sensor[cells[k, a]])
        if w <= 0.0:
            continue
        for a in range(4):
            ml = mc[k, a, 0] + mc[k, a, 1] + mc[k, a, 2] + mc[k, a, 3]
            i = cells[k, a]
            for c in range(3):
                acc = ml * dq[i, c]
                for b in range(4):
                    acc -= mc[k, a, b] * dq[cells[k, b], c]
                aec[k, a, c] += w * acc


class MassCorrection:
    """The gated consistent-mass correction on one discretization.

    Args:
        disc: The discretization.
        kappa: Thin-layer depth κ [m]; the sensor's regularisation is ``SENSOR_DEPTH κ``.
    """

    def __init__(self, disc: Discretization, kappa: float) -> None:
        n = disc.n_owned_cells
        self.mc_all = element_masses(disc.cell_nodes[:n], disc.coords)
        self.delta = SENSOR_DEPTH * float(kappa)
        self._key: tuple[int, int] | None = None
        self._arrays: dict[str, np.ndarray] = {}

    def _on(self, region: ActiveSet) -> dict[str, np.ndarray]:
        key = (id(region), region.rebuilds)
        if key != self._key:
            self._arrays = {"cells": region.compact_cells("owned"),
                            "mc": np.ascontiguousarray(self.mc_all[region.owned]),
                            "buf": np.empty((region.owned.size, 4, 5))}
            self._key = key
        return self._arrays

    def add(self, aec: np.ndarray, high: np.ndarray, boundary: np.ndarray, h: np.ndarray,
            mass: np.ndarray, region: ActiveSet, also_max: np.ndarray | None = None) -> None:
        """Add the gated correction to the antidiffusive contributions (collective).

        Args:
            aec: (n_active_owned, 4, 3) antidiffusive element contributions, updated.
            high: (n_active_owned, 4, 3) high-order element contributions ``dt R^H``.
            boundary: (n, 3) nodal high-order boundary terms times dt (compact).
            h: (n,) depth at the start of the step (compact).
            mass: (n,) lumped mass (compact).
            region: The active set.
            also_max: (k, n) compact values the caller needs reduced (max over the ranks, in
                place): done in this exchange.
        """
        arrays = self._on(region)
        buf, cells = arrays["buf"], arrays["cells"]
        sensor_sums(cells, h, high, buf)
        sums = region.cell_sum(buf, also_max)  # one exchange for ΔQ^H, the sensor, also_max
        dq, sensor = np.empty((sums.shape[0], 3)), np.empty(sums.shape[0])
        rates_and_sensor(sums, boundary, mass, self.delta, dq, sensor)
        add_correction(cells, arrays["mc"], dq, sensor, aec)
