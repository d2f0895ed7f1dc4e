"""Low-order Rusanov (graph-viscosity) element contributions, well-balanced and positive.

For every owned cell ``K`` and node pair ``i != j`` of ``K``, with ``β_ij`` the antisymmetric part
of ``∫_K φ_i ∇φ_j``, the hydrostatically reconstructed depths
``h*_ij = max(0, h_i + Z_i - max(Z_i, Z_j))`` (Audusse et al. 2004), ``q*_ij = h*_ij u_i`` and the
Rusanov viscosity ``d_ij = λ_ij |β_ij|``,
``λ_ij = max(|u_i·n| + sqrt(g h_i), |u_j·n| + sqrt(g h_j))``:

    mass_i += -β_ij·(q*_ij + q*_ji) + d_ij (h*_ji - h*_ij)
    mom_i  += -(β_ij·u_i) q*_ij - (β_ij·u_j) q*_ji + d_ij (q*_ji - q*_ij)
    mom_i  += -g h_i Σ_j (η̂_ij - η_i) ∫_K φ_i ∇φ_j   (j over all nodes of K; Σ_j ∫φ_i∇φ_j = 0)

where ``η̂_ij = η_j - (1 - w_j) max(Z_j - η_i, 0)`` (:func:`bank_drop`): ``η_j`` where
j is wet (``h_j >= δ``), ``h_j + min(Z_j, η_i)`` where it is dry — a dry bank above the water
pushes nothing — and continuous in between (no mask that switches on round-off). Each
cell's mass contributions sum to zero (conservation), vanish for
a lake at rest (also with emerged dry ground), and the update is positive for
``dt <= m_i / Σ_j (d_ij + |β_ij·u_i|)`` (this bound, with the eigenvalues ``|u·n| ± sqrt(g h)`` of
the full system, sets the time step by default). The depth alone stays non-negative up to
``dt <= m_i / Σ_j (d_ij + β_ij·u_i)``: node i loses ``h*_ij (d_ij + β_ij·u_i) >= 0`` to each pair
and ``h*_ij <= h_i``, and at an interior node ``Σ_j β_ij = 0``, so the advective part drops out
(up to twice the step in a fast flow; ``numerics.step_bound: positivity``). This is the
low-order scheme of seed eq. 15 that the FCT limiter blends with TG2-PC.
"""

from __future__ import annotations

import numba
import numpy as np

#: Growth of the wet-weight width with the bank height (see :func:`bank_drop`).
BANK_SLOPE = 1e-4


@numba.njit(cache=True)
def bank_drop(h, drop, delta):
    """Part of a bank height ``drop >= 0`` that a node of depth ``h`` stands above the water.

    ``(1 - w) drop`` with the wet weight ``w = min(1, max(h, 0) / (δ + BANK_SLOPE drop))``:
    all of it where the node is dry, none where it is wet, continuous in between. The width
    grows with the bank so that the Lipschitz constant ``drop / (δ + ε drop)`` stays below
    ``1/ε``: with a fixed ``δ = κ`` a round-off change of a film draining over the 20 m cliff
    moved the result by 4e-4; a fixed ``δ = 1e3 κ`` treated films under 1 mm as banks and
    slowed a 1 m flow on a steep coarse DEM (outflow 0.004 m³ instead of 390 m³).
    """
    return (1.0 - min(1.0, max(h, 0.0) / (delta + BANK_SLOPE * drop))) * drop


@numba.njit(cache=True, inline="always")
def _scale(h, kappa):
    """:func:`velocity_factor` of one node (the same operations)."""
    hp = max(h, 0.0)
    hk = max(h, kappa)
    return 2.0 * hp / (hp * hp + hk * hk)


@numba.njit(cache=True)
def nodal_velocity(h, qx, qy, kappa, ux, uy):  # noqa: D103 - documented in velocity()
    for i in range(h.shape[0]):
        f = _scale(h[i], kappa)
        ux[i] = qx[i] * f
        uy[i] = qy[i] * f


@numba.njit(cache=True)
def velocity_on(h, qx, qy, nodes, kappa, ux, uy, ux_on, uy_on):
    """:func:`velocity` at the local ``nodes`` only: into ``ux``, ``uy`` there and compact.

    ``ux_on[k] = ux[nodes[k]]`` (the same operations as :func:`nodal_velocity`).
    """
    for k in range(nodes.shape[0]):
        i = nodes[k]
        f = _scale(h[i], kappa)
        ux_on[k] = qx[i] * f
        uy_on[k] = qy[i] * f
        ux[i] = ux_on[k]
        uy[i] = uy_on[k]


def velocity_factor(h: np.ndarray, kappa: float) -> np.ndarray:
    """``2 max(h, 0) / (max(h, 0)² + max(h, κ)²)``: ``u = q × factor`` (see :func:`velocity`).

    The one formula of the desingularised velocity; :func:`nodal_velocity` is its compiled
    loop (the same operations, the same bits).
    """
    hp = np.maximum(h, 0.0)
    return 2.0 * hp / (hp * hp + np.maximum(h, kappa) * np.maximum(h, kappa))


def velocity(h, qx, qy, kappa: float, ux, uy) -> None:
    """Nodal velocity, desingularised: ``u = 2 h q / (h² + max(h, κ)²)`` (= q/h for h >= κ).

    Written into ``ux``, ``uy``. Kurganov & Petrova (2007): a draining layer keeps a bounded
    velocity instead of ``q / h → ∞``; the formula is Lipschitz in (h, q) down to h = 0 (no
    dry mask).
    """
    nodal_velocity(h, qx, qy, kappa, ux, uy)


def pair_norms(beta: np.ndarray) -> np.ndarray:
    """``|β_ab| = sqrt(β_x² + β_y²)`` of :func:`pair_coefficients` (n, 6): the pairs' norms."""
    return np.sqrt(beta[..., 0] * beta[..., 0] + beta[..., 1] * beta[..., 1])


PAIRS = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def pair_coefficients(C: np.ndarray) -> np.ndarray:
    """``β_ab`` = antisymmetric part of ``∫_K φ_a ∇φ_b`` for the 6 node pairs of each cell.

    Args:
        C: (n, 4, 4, 2) cell integrals.

    Returns:
        (n, 6, 2) array in the order of :data:`PAIRS`.
    """
    a, b = PAIRS[:, 0], PAIRS[:, 1]
    return np.ascontiguousarray(0.5 * (C[:, a, b, :] - C[:, b, a, :]))


@numba.njit(cache=True, inline="always")
def _pressure(C, k, H, Z, G, E, tol, out):
    """Cell k's pressure rates ``-g h_i Σ_j (η̂_ij - η_i) ∫_K φ_i ∇φ_j`` into ``out[k]`` (mass 0).

    ``H, Z, G, E``: the cell's nodal depth, bed, gravity and surface ``h + Z`` (tuples).
    """
    for a in range(4):
        eta_i = E[a]
        p1 = 0.0
        p2 = 0.0
        for b in range(4):
            if b == a:
                continue
            eta_hat = E[b] - bank_drop(H[b], max(Z[b] - eta_i, 0.0), tol)
            p1 += (eta_hat - eta_i) * C[k, a, b, 0]
            p2 += (eta_hat - eta_i) * C[k, a, b, 1]
        out[k, a, 0] = 0.0
        out[k, a, 1] = -G[a] * H[a] * p1
        out[k, a, 2] = -G[a] * H[a] * p2


@numba.njit(cache=True)
def low_order_pass(cells, beta, beta_norm, C, h, qx, qy, z, ux, uy, g, tol, out, cap,
                   signed=False):
    """Low-order rates per cell and node, and the time-step capacity per node, in one pass.

    Every unordered pair is visited once: its mass and momentum fluxes are antisymmetric
    (``β_ba = -β_ab``, ``d_ab = d_ba``), so node a receives ``+F`` and node b ``-F``.

    Args:
        cells: (n, 4) local node indices of the cells to process.
        beta: (n, 6, 2) pair coefficients (:func:`pair_coefficients`).
        beta_norm: (n, 6) their norms ``sqrt(β_x² + β_y²)`` (:func:`pair_norms`).
        C: (n, 4, 4, 2) ``∫_K φ_i ∇φ_j`` (for the pressure term).
        h: Nodal depth (ghosts up to date).
        qx: Nodal x-momentum.
        qy: Nodal y-momentum.
        z: Nodal elevation.
        ux: Nodal x-velocity (see :func:`velocity`).
        uy: Nodal y-velocity.
        g: Nodal gravity of the pressure term, ``g`` or the slope form's ``G``.
        tol: Depth δ of the wet weight (:func:`bank_drop`).
        out: (n, 4, 3) low-order rates (overwritten; not multiplied by dt).
        cap: (n, 4) ``Σ_j (d_ij + |β_ij·u_i|)`` per cell and node (overwritten).
        signed: Capacities ``Σ_j (d_ij + β_ij·u_i)`` instead, the depth's own bound
            (``numerics.step_bound: positivity``, :meth:`Transport.stable_dt
            <fem_runout.tg2.transport.Transport.stable_dt>`).
    """
    for k in range(cells.shape[0]):
        # the cell's node values, read once (the stores to out and cap below could alias
        # them for the compiler): the same operations, the same bits
        n0, n1, n2, n3 = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        H = (h[n0], h[n1], h[n2], h[n3])
        Z = (z[n0], z[n1], z[n2], z[n3])
        G = (g[n0], g[n1], g[n2], g[n3])
        UX = (ux[n0], ux[n1], ux[n2], ux[n3])
        UY = (uy[n0], uy[n1], uy[n2], uy[n3])
        E = (H[0] + Z[0], H[1] + Z[1], H[2] + Z[2], H[3] + Z[3])
        _pressure(C, k, H, Z, G, E, tol, out)
        for a in range(4):
            cap[k, a] = 0.0
        # the nodes' wave speeds, once per cell (the pairs below take them: the same bits)
        c = (np.sqrt(G[0] * max(H[0], 0.0)), np.sqrt(G[1] * max(H[1], 0.0)),
             np.sqrt(G[2] * max(H[2], 0.0)), np.sqrt(G[3] * max(H[3], 0.0)))
        for p in range(6):
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            bx = beta[k, p, 0]
            by = beta[k, p, 1]
            zm = max(Z[a], Z[b])
            hs_ij = max(0.0, E[a] - zm)
            hs_ji = max(0.0, E[b] - zm)
            nb = beta_norm[k, p]
            uxi, uyi, uxj, uyj = UX[a], UY[a], UX[b], UY[b]
            bu_i = bx * uxi + by * uyi
            bu_j = bx * uxj + by * uyj
            d = max(abs(bu_i) + c[a] * nb, abs(bu_j) + c[b] * nb)
            fm = -(hs_ij * bu_i + hs_ji * bu_j) + d * (hs_ji - hs_ij)
            fx = -bu_i * hs_ij * uxi - bu_j * hs_ji * uxj + d * (hs_ji * uxj - hs_ij * uxi)
            fy = -bu_i * hs_ij * uyi - bu_j * hs_ji * uyj + d * (hs_ji * uyj - hs_ij * uyi)
            out[k, a, 0] += fm
            out[k, a, 1] += fx
            out[k, a, 2] += fy
            out[k, b, 0] -= fm
            out[k, b, 1] -= fx
            out[k, b, 2] -= fy
            # node b's coefficient of the pair is β_ba = -β_ab: it loses h*_ji (d - β_ab·u_j)
            cap[k, a] += d + (bu_i if signed else abs(bu_i))
            cap[k, b] += d + (-bu_j if signed else abs(bu_j))


@numba.njit(cache=True)
def reconstructed_surface(cells, h, z, tol, out):
    """Per-cell free surface for the predictor: η on wet nodes, ``min(Z, top) + h`` on dry ones.

    ``top`` is the highest surface of the cell's wet part, ``max_a (η_a - (1 - w_a)(Z_a -
    Z_min))`` (a dry node counts with the cell's lowest bed), and a node gets
    ``η_a - (1 - w_a) max(Z_a - top, 0)`` with the wet weight ``w_a`` (:func:`bank_drop`):
    continuous in the data, a lake at rest (also with emerged dry ground) gives a constant η̃.

    Args:
        cells: (n, 4) local node indices.
        h: Nodal depth.
        z: Nodal elevation.
        tol: Depth δ of the wet weight.
        out: (n, 4) output, the DQ1 coefficients of η̃.
    """
    for k in range(cells.shape[0]):
        nodes = cells[k]
        zmin = np.inf
        for a in range(4):
            zmin = min(zmin, z[nodes[a]])
        top = -np.inf
        for a in range(4):
            i = nodes[a]
            top = max(top, h[i] + z[i] - bank_drop(h[i], z[i] - zmin, tol))
        for a in range(4):
            i = nodes[a]
            out[k, a] = h[i] + z[i] - bank_drop(h[i], max(z[i] - top, 0.0), tol)


@numba.njit(cache=True)
def bar_state_extrema(cells, beta, beta_norm, h, ux, uy, z, g, speed, vmax, vmin):
    """Extend per-node momentum bounds by the momenta of the low-order bar states.

    The Rusanov update of an interior node is ``U_i + dt/m_i Σ_j 2 d_ij (Ū_ij - U_i)``, a
    convex combination of the bar states ``Ū_ij = (U*_i + U*_j)/2 - β_ij·(F(U*_j) -
    F(U*_i)) / (2 d_ij)`` of the hydrostatically reconstructed states ``U*`` (Guermond &
    Popov 2016; Hajduk & Kuzmin 2022): they are the states the low-order method itself
    reaches next to each node. On a slope they include the hydrostatic pressure jump of the
    reconstruction, so a uniform sheet on an incline has room for the TG2 correction.

    Args:
        cells: (n, 4) local nodes of every local cell (ghost cells too: the whole patch).
        beta: (n, 6, 2) pair coefficients of the same cells.
        beta_norm: (n, 6) their norms ``|β_ij|``.
        h: Nodal depth.
        ux: Nodal x-velocity (desingularised).
        uy: Nodal y-velocity.
        z: Nodal elevation.
        g: Nodal gravity of the pressure term (``g`` or ``G``).
        speed: Nodal wave speed ``sqrt(g max(h, 0))``.
        vmax: (2, n_nodes) upper bounds of (hu, hv), extended in place.
        vmin: (2, n_nodes) lower bounds, extended in place.
    """
    for k in range(cells.shape[0]):
        for p in range(6):
            i = cells[k, PAIRS[p, 0]]
            j = cells[k, PAIRS[p, 1]]
            bx = beta[k, p, 0]
            by = beta[k, p, 1]
            nb = beta_norm[k, p]
            zm = max(z[i], z[j])
            hi_ = max(0.0, h[i] + z[i] - zm)
            hj_ = max(0.0, h[j] + z[j] - zm)
            bu_i = bx * ux[i] + by * uy[i]
            bu_j = bx * ux[j] + by * uy[j]
            d = max(abs(bu_i) + speed[i] * nb, abs(bu_j) + speed[j] * nb)
            if d <= 0.0:
                continue
            dp = 0.5 * (0.5 * (g[i] + g[j])) * (hj_ * hj_ - hi_ * hi_)
            v0 = 0.5 * (hi_ * ux[i] + hj_ * ux[j]) - (bu_j * hj_ * ux[j] - bu_i * hi_ * ux[i]
                                                      + dp * bx) / (2.0 * d)
            v1 = 0.5 * (hi_ * uy[i] + hj_ * uy[j]) - (bu_j * hj_ * uy[j] - bu_i * hi_ * uy[i]
                                                      + dp * by) / (2.0 * d)
            vmax[0, i] = max(vmax[0, i], v0)
            vmin[0, i] = min(vmin[0, i], v0)
            vmax[0, j] = max(vmax[0, j], v0)
            vmin[0, j] = min(vmin[0, j], v0)
            vmax[1, i] = max(vmax[1, i], v1)
            vmin[1, i] = min(vmin[1, i], v1)
            vmax[1, j] = max(vmax[1, j], v1)
            vmin[1, j] = min(vmin[1, j], v1)
