"""UFL forms of the TG2-PC transport step (seed §3.1, eqs. 9–12): the definition.

Runs compute the same integrals cell by cell (:mod:`.predictor`, :mod:`.edges`);
``tests/test_cell_kernels.py`` assembles these forms with DOLFINx and compares.

Predictor (eq. 10, first line), into DG0 with the exact DG0 mass ``|K|``:

    |K| Q_K^{n+1/2} = ∫_K Q^n - dt/2 ∫_K (∇·F(Q^n) + B(Q^n) ∇Z)

The pressure and bed terms are written together as ``g h ∇η̃`` (``∇(g h²/2) + g h ∇Z``), with
``η̃`` the per-cell free surface of :func:`~fem_runout.tg2.low_order.reconstructed_surface`, so a
lake at rest is exact even in cells where the shore cuts through.

Corrector (eq. 10, second line), tested with discontinuous Q1 functions ``ψ`` so that the
assembled vector holds the element contributions per cell and node — the arrays the FCT limiter
works on:

    A_H[K, i] = dt (F(Q_K^{n+1/2}), ∇ψ_i)_K
              - dt Σ_{e ∈ ∂K} ∫_e g h̄_e (η_- - η_+) n_+ · ½(ψ_i^+ + ψ_i^-) ds

The edge term is the path-conservative integral of the non-conservative product (eqs. 11–12,
linear path ``Ψ(s)``, exact trapezoidal/midpoint rule): ``∫_0^1 g h(Ψ(s)) ∂_s Z ds = g h̄ [Z]``,
joined with the jump of the conservative pressure ``[g h²/2] = g h̄ [h]`` of the DG0 states, which
gives ``g h̄ [η]``; zero for a lake at rest (Prop. 3.1). A dry cell whose bed stands above the
neighbour's surface is given that surface (it pushes nothing). Each edge term is shared equally
by the two cells. Boundary fluxes are added nodally by the solver.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, mesh

from fem_runout.mesh import Discretization, rectangle_facets
from fem_runout.tg2.low_order import BANK_SLOPE


def predictor_form(
    state: tuple[fem.Function, fem.Function, fem.Function],
    velocity: tuple[fem.Function, fem.Function],
    eta_cell: fem.Function,
    W0: fem.FunctionSpace,
    dt: fem.Constant,
    g: fem.Constant | fem.Function,
) -> fem.Form:
    """Linear form of the DG0 predictor increment (eq. 10, first line).

    The form gives ``-dt/2 ∫_K (∇·F + B∇Z)``; the solver adds the exact cell mean of the Q1 state
    (``∫_K Q^n / |K|`` is the mean of the four nodal values on a parallelogram), which keeps the
    increment free of the round-off of ``∫_K Q^n``.

    Args:
        state: Q1 functions h, hu, hv at t^n.
        velocity: Q1 nodal velocity (u, v).
        eta_cell: DQ1 free surface η̃ per cell.
        W0: DG0 space with 3 components (h, hu, hv).
        dt: Time step (the transport step).
        g: Gravity: a constant, or the slope form's DG0 ``G`` per cell.
    """
    h, hu, hv = state
    q = ufl.as_vector([hu, hv])
    u = ufl.as_vector(velocity)
    conv = ufl.div(ufl.outer(q, u))
    rate = ufl.as_vector(
        [ufl.div(q), conv[0] + g * h * eta_cell.dx(0), conv[1] + g * h * eta_cell.dx(1)]
    )
    w = ufl.TestFunction(W0)
    dx = ufl.dx(metadata={"quadrature_degree": 3})
    return fem.form(ufl.inner(-0.5 * dt * rate, w) * dx)


def corrector_form(
    cell_state: fem.Function,
    cell_velocity: fem.Function,
    cell_eta: fem.Function,
    Wd: fem.FunctionSpace,
    dt: fem.Constant,
    g: fem.Constant | fem.Function,
    dry: fem.Constant,
    z: fem.Function,
    measures: tuple[tuple[ufl.Measure, ufl.Measure | None], ...],
    spacing: tuple[float, float] = (1.0, 1.0),
) -> list[fem.Form]:
    """Linear forms of the high-order corrector element contributions (eqs. 10–12).

    One form per ``(dS, ds_open)`` pair of ``measures`` (:func:`facet_measures`:
    vertical, then horizontal facets); the cell integrals go into the first. Their sum is the
    corrector; split this way every dof gets one facet term per form, so the assembled sums
    do not depend on the partition.

    Args:
        cell_state: DG0 (h, hu, hv) at t^{n+1/2}.
        cell_velocity: DG0 velocity at t^{n+1/2}.
        cell_eta: DG0 free surface ``h_K + Z̃_K``.
        Wd: Discontinuous Q1 space with 3 components.
        dt: Time step.
        g: Gravity: a constant, or the slope form's DG0 ``G`` per cell.
        dry: Depth δ of the wet weight ``min(1, h/δ)`` (the thin depth κ).
        z: Q1 bed elevation (for the ghost state of open boundaries).
        measures: ``(dS, ds_open)`` pairs; ``ds_open`` None where no side is open.
        spacing: Cell size (dx, dy) of the structured grid.

    On an open side the ghost cell continues the bed with its slope (zero-gradient depth and
    velocity): the jump ``[η] = ∂Z/∂n Δn`` across the boundary, with half weight because the
    boundary node owns half a patch, gives the boundary nodes the normal bed-slope force that
    interior nodes get from their edges (a uniform sheet on a slope stays uniform).
    """
    psi = ufl.TestFunction(Wd)
    hk, qx, qy = cell_state[0], cell_state[1], cell_state[2]
    ux, uy = cell_velocity[0], cell_velocity[1]
    flux = ufl.as_matrix([[qx, qy], [qx * ux, qx * uy], [qy * ux, qy * uy]])
    n = ufl.FacetNormal(Wd.mesh)
    hp, hm = hk("+"), hk("-")
    ep, em = cell_eta("+"), cell_eta("-")
    # a dry cell whose surface stands above the neighbour's takes the neighbour's, blended by
    # the wet weight min(1, h/δ) (continuous: no switch on round-off)
    # (low_order.bank_drop: the ramp's width grows with the bank height)
    drop_m, drop_p = ufl.max_value(em - ep, 0.0), ufl.max_value(ep - em, 0.0)
    dry_m = 1.0 - ufl.min_value(1.0, ufl.max_value(hm, 0.0) / (dry + BANK_SLOPE * drop_m))
    dry_p = 1.0 - ufl.min_value(1.0, ufl.max_value(hp, 0.0) / (dry + BANK_SLOPE * drop_p))
    em_eff = em - dry_m * drop_m
    ep_eff = ep - dry_p * drop_p
    # the slope form's per-cell G is averaged over the facet (the seed's g is a constant)
    g_face = g if isinstance(g, fem.Constant) else ufl.avg(g)
    fluct = g_face * 0.5 * (hp + hm) * (em_eff - ep_eff)
    psi_m = ufl.as_vector([psi[1], psi[2]])
    dx = ufl.dx(metadata={"quadrature_degree": 1})
    normal_size = abs(n[0]) * spacing[0] + abs(n[1]) * spacing[1]
    jump = ufl.dot(ufl.grad(z), n) * normal_size
    forms = []
    for k, (dS, ds_open) in enumerate(measures):
        form = -dt * fluct * ufl.dot(n("+"), 0.5 * (psi_m("+") + psi_m("-"))) * dS
        if k == 0:
            form = dt * ufl.inner(flux, ufl.grad(psi)) * dx + form
        if ds_open is not None:
            form = form - dt * 0.5 * g * hk * jump * ufl.dot(n, psi_m) * ds_open
        forms.append(fem.form(form))
    return forms


def facet_measures(disc: Discretization) -> tuple[tuple[ufl.Measure, ufl.Measure | None], ...]:
    """``(dS, ds_open)`` restricted to the vertical facets, then to the horizontal ones.

    A node of a cell lies on exactly one vertical and one horizontal edge of that cell, so a
    form with the cell integrals and the vertical facets, and one with the horizontal facets,
    each give every discontinuous-Q1 dof at most one facet term: their sums (also across
    ranks) are a single addition, the same bits on any partition (:mod:`fem_runout.cellsum`).
    ``ds_open`` is None when every side is a wall. Tags: 1/2 vertical/horizontal facets,
    3/4 vertical/horizontal facets of the open sides.
    """
    msh = disc.mesh
    facets, mid, on = rectangle_facets(disc)
    fx = (mid[:, 0] - disc.extent[0]) / disc.spacing[0]
    vertical = np.abs(fx - np.round(fx)) < 0.25
    values = np.where(vertical, 1, 2).astype(np.int32)
    open_sides = [s.name for s in disc.sides if s.kind == "open"]
    for name in open_sides:
        values[on[name]] += 2
    tags = mesh.meshtags(msh, msh.topology.dim - 1, facets, values)
    md = {"quadrature_degree": 1}
    out = []
    for k in (1, 2):
        dS = ufl.Measure("dS", domain=msh, subdomain_data=tags, subdomain_id=k, metadata=md)
        ds = (ufl.Measure("ds", domain=msh, subdomain_data=tags, subdomain_id=k + 2,
                          metadata=md) if open_sides else None)
        out.append((dS, ds))
    return tuple(out)
