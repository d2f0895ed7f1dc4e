"""TG2-PC's high-order element contributions on the active set (seed eqs. 9–12).

The predictor (DG0) and the corrector (discontinuous Q1) whose UFL forms are in :mod:`.forms`,
computed cell by cell by numba kernels (:mod:`.predictor`, :mod:`.edges`; tested against the
forms assembled by DOLFINx) on the active cells only (:class:`~fem_runout.active.ActiveSet`).
Per step the work covers the *wide* cells (the active ones and their neighbours, whose DG0
states the corrector's edge terms read):

1. the per-cell free surface η̃ (:func:`.low_order.reconstructed_surface`);
2. the predictor on the active local cells, ghosts included (the same kernel on the same
   data as on the owning rank, so no exchange is needed), giving ``Q_K^{n+1/2}``;
3. the corrector on the active owned cells, from their and their neighbours' DG0 states.

Every term carries a factor ``h`` or ``q`` (``∇·q``, ``q⊗u``, ``g h ∇η``, the edge
fluctuation ``g h̄ [η]``, the open-side ``g h ∂Z/∂n``), so the cells left out would give exact
zeros. The predictor's vector is zeroed whole at every rebuild of the active set and on the
wide cells' dofs per step; nothing else writes to it, so every entry off them stays zero.
"""

from __future__ import annotations

import basix.ufl
import numba
import numpy as np
from dolfinx import fem, la

from fem_runout.active import ActiveSet
from fem_runout.mesh import Discretization
from fem_runout.quadmesh import rectangle_edges
from fem_runout.tg2.edges import corrector_cells, edge_dzdn
from fem_runout.tg2.low_order import reconstructed_surface
from fem_runout.tg2.predictor import predictor_cells

__all__ = ["HighOrder"]


@numba.njit(cache=True)
def _put(values, dofs, data):
    """``values[dofs[k, a]] = data[k, a]``."""
    for k in range(dofs.shape[0]):
        for a in range(dofs.shape[1]):
            values[dofs[k, a]] = data[k, a]


@numba.njit(cache=True)
def _put_cell_means(values, dofs, nodal, cells):
    """``values[dofs[k]] = mean of nodal[cells[k, :]]`` (sum in node order, then / 4)."""
    for k in range(cells.shape[0]):
        values[dofs[k]] = (((nodal[cells[k, 0]] + nodal[cells[k, 1]]) + nodal[cells[k, 2]])
                           + nodal[cells[k, 3]]) / 4.0


@numba.njit(cache=True)
def _zero_blocks(values, blocks, bs):
    """Zero the ``bs`` entries of every block index in ``blocks`` (any shape)."""
    flat = blocks.reshape(-1)
    for k in range(flat.shape[0]):
        for c in range(bs):
            values[bs * flat[k] + c] = 0.0


@numba.njit(cache=True)
def _mean(values, w, k):
    """``Σ_a w[k, a] values[a]``, or their plain mean ``0.25 Σ_a values[a]`` (``w`` empty).

    The weighted mean is written ``v_0 + Σ_a w_a (v_a - v_0)``: exact for a constant.
    """
    if w.shape[0] == 0:
        return 0.25 * ((((0.0 + values[0]) + values[1]) + values[2]) + values[3])
    acc = 0.0
    for a in range(1, 4):
        acc += w[k, a] * (values[a] - values[0])
    return values[0] + acc


@numba.njit(cache=True)
def _cell_states(cells, h, qx, qy, cell_eta, b, dof0, dofs0, area, w, kappa, Qk, uk, etak):
    """DG0 states at the half step from the predictor increments ``b`` (eq. 10, first line).

    ``Q_K = mean(Q) + b_K / |K|``, ``η_K = mean(η̃) + b_K[h] / |K|`` and the desingularised
    velocity of ``Q_K`` (:func:`.low_order.velocity_factor`, the same operations), in one
    pass. The mean is the DG0 projection of the Q1 interpolant the predictor starts from:
    ``Σ_a (∫_K φ_a / |K|) Q_a`` (weights ``w``), on a parallelogram the plain mean of the four
    nodal values (``w`` empty).
    """
    vals = np.empty((4, 4))
    for k in range(cells.shape[0]):
        for a in range(4):
            i = cells[k, a]
            vals[0, a] = h[i]
            vals[1, a] = qx[i]
            vals[2, a] = qy[i]
            vals[3, a] = cell_eta[k, a]
        d = dof0[k]
        dh = b[3 * d] / area[k]
        v0 = _mean(vals[0], w, k) + dh
        v1 = _mean(vals[1], w, k) + b[3 * d + 1] / area[k]
        v2 = _mean(vals[2], w, k) + b[3 * d + 2] / area[k]
        Qk[3 * d], Qk[3 * d + 1], Qk[3 * d + 2] = v0, v1, v2
        etak[dofs0[k]] = _mean(vals[3], w, k) + dh
        hp = max(v0, 0.0)
        hk = max(v0, kappa)
        f = 2.0 * hp / (hp * hp + hk * hk)
        uk[2 * d], uk[2 * d + 1] = v1 * f, v2 * f


class HighOrder:
    """The DG fields and vectors of the predictor and corrector.

    Args:
        disc: The discretization.
        state: Q1 functions (h, hu, hv).
        velocity: Q1 nodal velocity (ux, uy).
        z: Q1 bed elevation.
        gravity: g [m/s²].
        kappa: Thin depth κ (velocity desingularisation, wet weight of the edge terms).
        slope: True for the slope form (per-cell ``G`` instead of the constant ``g``).
    """

    def __init__(self, disc: Discretization, state: tuple[fem.Function, ...],
                 velocity: tuple[fem.Function, fem.Function], z: fem.Function,
                 gravity: float, kappa: float, slope: bool) -> None:
        self.disc, self.kappa = disc, kappa
        self.h, self.hu, self.hv = state
        self.velocity, self.z = velocity, z
        msh = disc.mesh
        W0 = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 0, shape=(3,)))
        U0 = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 0, shape=(2,)))
        S0 = fem.functionspace(msh, ("DG", 0))
        Sd = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 1))
        self.eta_t, self.Qk = fem.Function(Sd), fem.Function(W0)
        self.uk, self.etak = fem.Function(U0), fem.Function(S0)
        self.gk = fem.Function(S0)  # per-cell G of the slope form (mean of the nodes')
        # views of the functions' arrays, taken once (each ``x.array`` builds a new view)
        self._a = {name: f.x.array for name, f in (
            ("h", self.h), ("hu", self.hu), ("hv", self.hv), ("z", z), ("ux", velocity[0]),
            ("uy", velocity[1]), ("eta_t", self.eta_t), ("Qk", self.Qk), ("uk", self.uk),
            ("etak", self.etak), ("gk", self.gk))}
        self.g_const = -1.0 if slope else float(gravity)
        #: the cell–edge data of the corrector (the rectangle's built here, a gmsh mesh's given)
        self.edges = disc.edges if disc.edges is not None else rectangle_edges(disc)
        self._dzdn: np.ndarray | None = None  # ∇Z·n at the edges, once Z is set
        self.b_pred = la.vector(W0.dofmap.index_map, 3)
        self._b_pred = self.b_pred.array
        nc = disc.cell_nodes.shape[0]
        self._dofs = {
            "dof0": np.asarray(W0.dofmap.list[:nc, 0], dtype=np.int64),
            "dofs0": np.asarray(S0.dofmap.list[:nc, 0], dtype=np.int64),
            "dofsd": np.asarray(Sd.dofmap.list[:nc], dtype=np.int64),
        }
        if not np.array_equal(self._dofs["dof0"], U0.dofmap.list[:nc, 0]):
            raise RuntimeError("DG0 spaces with different cell numbering")
        self._key = -1
        self._on: dict[str, np.ndarray] = {}

    def contributions(self, active: ActiveSet, gn: np.ndarray | None, dt: float) -> np.ndarray:
        """Return ``dt A_H[K, i]`` (n_active_owned, 4, 3) of the active owned cells.

        Args:
            active: The active set.
            gn: Nodal ``G`` of the slope form, or None.
            dt: Time step.
        """
        on = self._arrays(active)
        a = self._a
        h, hu, hv, z = a["h"], a["hu"], a["hv"], a["z"]
        cells = on["cells"]
        cell_eta = on["cell_eta"]
        b_pred = self._b_pred
        reconstructed_surface(cells, h, z, self.kappa, cell_eta)
        _put(a["eta_t"], on["dofsd"], cell_eta)
        if gn is not None:
            _put_cell_means(a["gk"], on["dofs0"], gn, cells)
        _zero_blocks(b_pred, on["dof0"], 3)
        dofs, d = self._dofs, self.disc
        predictor_cells(active.cells, d.cell_nodes, d.coords, h, hu, hv, a["ux"], a["uy"],
                        a["eta_t"], dofs["dofsd"], a["gk"], dofs["dofs0"], self.g_const, dt,
                        dofs["dof0"], b_pred)
        _cell_states(cells, h, hu, hv, cell_eta, b_pred, on["dof0"], on["dofs0"],
                     on["area"], on["weight"], self.kappa, a["Qk"], a["uk"], a["etak"])
        return self._cell_by_cell(active, dt, on["out"])

    def _cell_by_cell(self, active: ActiveSet, dt: float, out: np.ndarray) -> np.ndarray:
        """Return the corrector of the active owned cells (:func:`.edges.corrector_cells`)."""
        e, dofs, d = self.edges, self._dofs, self.disc
        if self._dzdn is None:
            self._dzdn = edge_dzdn(self.z.x.array, d.coords, d.cell_nodes, e.normal)
        a = self._a
        corrector_cells(active.owned, dofs["dof0"], dofs["dofs0"], a["Qk"], a["uk"],
                        a["etak"], a["gk"], self.g_const,
                        self.kappa, dt, e.neighbour, e.kind, e.normal, e.length, e.depth,
                        e.corner_edges, e.grad_centre, self._dzdn, out)
        return out

    def _arrays(self, active: ActiveSet) -> dict[str, np.ndarray]:
        """Return the wide cells' nodes, dofs, buffers; zero the predictor's vector per rebuild."""
        if self._key == active.rebuilds:
            return self._on
        d, w = self.disc, active.wide
        dofs = self._dofs
        self._on = {
            "cells": np.ascontiguousarray(d.cell_nodes[w]),
            "dof0": dofs["dof0"][w], "dofs0": dofs["dofs0"][w],
            "dofsd": dofs["dofsd"][w],
            "area": d.cell_area[w],
            "weight": np.empty((0, 4)) if d.edges is None else d.edges.mean_weight[w],
            "cell_eta": np.empty((w.size, 4)),
            "out": np.empty((active.owned.size, 4, 3)),
        }
        self.b_pred.array[:] = 0.0
        self._key = active.rebuilds
        return self._on
