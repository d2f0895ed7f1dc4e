"""Edge-based Zalesak flux correction on cell–node arrays (seed eqs. 13–15), Lipschitz in the data.

The high-order (TG2-PC) and low-order (Rusanov) updates are both sums of element contributions
``A[K, i]`` to the nodes ``i`` of each cell ``K``. Their difference ``a_i = A_H - A_L`` is split
into antisymmetric node-pair fluxes and a per-node source (Kuzmin's element-to-edge
decomposition):

    a_i = Σ_{j ∈ K, j ≠ i} f_ij + μ_K,    f_ij = (a_i - a_j) / 4 = -f_ji,    μ_K = Σ_j a_j / 4

(``μ_K`` = 0 for the mass; the bed term makes it non-zero for the momenta). Each flux gets its
own factor, chosen with Zalesak's ratios at its two ends:

    P^±_i = Σ (positive/negative fluxes and sources into i),  Q^±_i = m_i (u^±_i - u^L_i),
    R^±_i = min(1, Q^±_i / P^±_i),
    f*_ij = min(R⁺_i, R⁻_j) f_ij if f_ij > 0 else min(R⁻_i, R⁺_j) f_ij,   μ*_i = R^±_i μ_K,

    m_i u_i^{n+1} = m_i u_i^L + Σ_K (Σ_j f*_ij + μ*_i)   ∈ [m_i u⁻_i, m_i u⁺_i].

Why per pair and not one factor per cell: with ``α_K = min_i R^±_i`` the sign of a round-off
sized ``a_j`` at one node picks ``R⁺`` or ``R⁻`` and switches the whole cell's correction by
O(1), so a 1e-15 change of the data moved the solution by 1e-2. Here every limited flux is a
Lipschitz function of the data (constant 1): ``f·R`` is continuous where ``P → 0`` because
``|f| <= |P|``, and where ``f`` changes sign both branches vanish. With bounds that are
themselves Lipschitz (max/min over patches, no wet/dry masks), the step is continuous.

The functions here are local to one rank; the solver sums ``P^±`` and the corrections over the
ranks that share a node between the calls (every cell is owned by one rank, so each flux is
counted once whatever the partition).
"""

from __future__ import annotations

import numba
import numpy as np

#: Node pairs (a, b), a < b, of a quadrilateral.
PAIRS = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


@numba.njit(cache=True, inline="always")
def _pair_sums(f, p_a, m_a, p_b, m_b):
    """Add a pair flux ``f`` (a gets ``+f``, b ``-f``) to ``P⁺_a, P⁻_a, P⁺_b, P⁻_b``."""
    if f > 0.0:
        return p_a + f, m_a, p_b, m_b - f
    return p_a, m_a + f, p_b - f, m_b


@numba.njit(cache=True, inline="always")
def _own_factor(f, rplus_i, rminus_i, rplus_j, rminus_j):
    """Zalesak's factor of a pair flux ``f`` from ``i`` to ``j`` (scalars: no array counts)."""
    return min(rplus_i, rminus_j) if f > 0.0 else min(rminus_i, rplus_j)


@numba.njit(cache=True)
def split_pairs(aec, flux, source):
    """Element-to-edge decomposition: ``f_ab = (a_a - a_b)/4`` per pair, ``μ = Σ_a a_a / 4``.

    Args:
        aec: (n, 4) element contributions of one variable.
        flux: (n, 6) pair fluxes in the order of :data:`PAIRS` (node a gets +f, b gets -f).
        source: (n,) per-node source of each cell.
    """
    for k in range(aec.shape[0]):
        source[k] = 0.25 * (aec[k, 0] + aec[k, 1] + aec[k, 2] + aec[k, 3])
        for p in range(6):
            flux[k, p] = 0.25 * (aec[k, PAIRS[p, 0]] - aec[k, PAIRS[p, 1]])


@numba.njit(cache=True)
def flux_sums(flux, source, out):
    """Positive/negative pair fluxes and sources per cell and node: ``out[K, a] = (P⁺, P⁻)``.

    Summed over the cells by :meth:`fem_runout.mesh.Discretization.cell_sum` (the same bits
    on any partition).
    """
    for k in range(flux.shape[0]):
        mu = source[k]
        for a in range(4):
            if mu > 0.0:
                out[k, a, 0] = mu
                out[k, a, 1] = 0.0
            else:
                out[k, a, 0] = 0.0
                out[k, a, 1] = mu
        for p in range(6):
            f = flux[k, p]
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            out[k, a, 0], out[k, a, 1], out[k, b, 0], out[k, b, 1] = _pair_sums(
                f, out[k, a, 0], out[k, a, 1], out[k, b, 0], out[k, b, 1])


@numba.njit(cache=True)
def split_flux_sums(aec, flux, source, out):
    """:func:`split_pairs` and :func:`flux_sums` of (h, hu, hv) in one pass, the same bits.

    Args:
        aec: (n, 4, 3) element contributions.
        flux: (3, n, 6) pair fluxes (output).
        source: (3, n) per-node source of each cell (output).
        out: (n, 4, 6) ``P⁺, P⁻`` of each variable at ``2c, 2c + 1`` (output).
    """
    for k in range(aec.shape[0]):
        for c in range(3):
            a0, a1, a2, a3 = aec[k, 0, c], aec[k, 1, c], aec[k, 2, c], aec[k, 3, c]
            mu = 0.25 * (a0 + a1 + a2 + a3)
            source[c, k] = mu
            pos, neg = (mu, 0.0) if mu > 0.0 else (0.0, mu)
            p0, p1, p2, p3 = pos, pos, pos, pos
            m0, m1, m2, m3 = neg, neg, neg, neg
            f01, f02, f03 = 0.25 * (a0 - a1), 0.25 * (a0 - a2), 0.25 * (a0 - a3)
            f12, f13, f23 = 0.25 * (a1 - a2), 0.25 * (a1 - a3), 0.25 * (a2 - a3)
            flux[c, k, 0], flux[c, k, 1], flux[c, k, 2] = f01, f02, f03
            flux[c, k, 3], flux[c, k, 4], flux[c, k, 5] = f12, f13, f23
            # the pairs in the order of PAIRS, as flux_sums adds them
            p0, m0, p1, m1 = _pair_sums(f01, p0, m0, p1, m1)
            p0, m0, p2, m2 = _pair_sums(f02, p0, m0, p2, m2)
            p0, m0, p3, m3 = _pair_sums(f03, p0, m0, p3, m3)
            p1, m1, p2, m2 = _pair_sums(f12, p1, m1, p2, m2)
            p1, m1, p3, m3 = _pair_sums(f13, p1, m1, p3, m3)
            p2, m2, p3, m3 = _pair_sums(f23, p2, m2, p3, m3)
            out[k, 0, 2 * c], out[k, 0, 2 * c + 1] = p0, m0
            out[k, 1, 2 * c], out[k, 1, 2 * c + 1] = p1, m1
            out[k, 2, 2 * c], out[k, 2, 2 * c + 1] = p2, m2
            out[k, 3, 2 * c], out[k, 3, 2 * c + 1] = p3, m3


@numba.njit(cache=True)
def limit_pairs(cells, flux, source, rplus, rminus, cap, out):
    """Limited fluxes ``f*`` and sources per cell and node (``out[K, a]``, overwritten).

    ``f*_ij = min(cap_i, cap_j, R⁺_i, R⁻_j) f_ij`` if ``f_ij > 0`` else ``min(cap_i, cap_j,
    R⁻_i, R⁺_j) f_ij``; a source at i gets ``min(cap_i, R^±_i)``. ``cap`` all ones is plain
    Zalesak.
    """
    for k in range(cells.shape[0]):
        mu = source[k]
        for a in range(4):
            i = cells[k, a]
            out[k, a] = mu * min(cap[i], rplus[i] if mu > 0.0 else rminus[i])
        for p in range(6):
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            i = cells[k, a]
            j = cells[k, b]
            f = flux[k, p]
            c = min(cap[i], cap[j])
            f *= min(c, _own_factor(f, rplus[i], rminus[i], rplus[j], rminus[j]))
            out[k, a] += f
            out[k, b] -= f


def zalesak_ratios(
    pplus: np.ndarray, pminus: np.ndarray, qplus: np.ndarray, qminus: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Nodal ratios ``R^± = min(1, Q^± / P^±)`` (1 where nothing is added).

    Args:
        pplus: Sum of positive contributions (>= 0).
        pminus: Sum of negative contributions (<= 0).
        qplus: Room above the low-order value, ``m_i (u_max - u^L)`` (negative counts as 0).
        qminus: Room below, ``m_i (u_min - u^L)`` (positive counts as 0).
    """
    rplus = np.ones_like(pplus)
    rminus = np.ones_like(pminus)
    pos = pplus > 0.0
    neg = pminus < 0.0
    with np.errstate(over="ignore"):  # Q/P overflows for subnormal P; min(1, inf) = 1 is right
        rplus[pos] = np.minimum(1.0, np.maximum(qplus[pos], 0.0) / pplus[pos])
        rminus[neg] = np.minimum(1.0, np.minimum(qminus[neg], 0.0) / pminus[neg])
    return rplus, rminus


@numba.njit(cache=True)
def synced_ratios(sums, mass, upper, lower, q_low, floor, rplus, rminus, soft):
    """:func:`zalesak_ratios` of (h, hu, hv) in one pass, and the depth's sign-free ratio.

    ``Q^± = m_i (u^± - u^L)`` from the bounds; ``sums[i, 2c]``, ``sums[i, 2c + 1]`` are
    ``P^±`` of variable ``c``. ``soft[i] = min(min(1, max(Q⁺_h, 0) / max(P⁺_h, floor_i)),
    min(1, min(Q⁻_h, 0) / min(P⁻_h, -floor_i)))`` (see
    :meth:`fem_runout.tg2.limiter.Limiter.correction`). The same operations as the array
    formulas, the same bits.

    Args:
        sums: (n, 6) ``P⁺, P⁻`` of h, hu, hv.
        mass: (n,) lumped masses.
        upper: (n, 3) upper bounds.
        lower: (n, 3) lower bounds.
        q_low: (n, 3) low-order state.
        floor: (n,) floor of ``|P|`` in the sign-free ratio.
        rplus: (3, n) ``R⁺`` (output).
        rminus: (3, n) ``R⁻`` (output).
        soft: (n,) the sign-free depth ratio (output).
    """
    for i in range(mass.shape[0]):
        for c in range(3):
            qp = mass[i] * (upper[i, c] - q_low[i, c])
            qm = mass[i] * (lower[i, c] - q_low[i, c])
            pp, pm = sums[i, 2 * c], sums[i, 2 * c + 1]
            rplus[c, i] = min(1.0, max(qp, 0.0) / pp) if pp > 0.0 else 1.0
            rminus[c, i] = min(1.0, min(qm, 0.0) / pm) if pm < 0.0 else 1.0
            if c == 0:
                up = min(1.0, max(qp, 0.0) / max(pp, floor[i]))
                down = min(1.0, min(qm, 0.0) / min(pm, -floor[i]))
                soft[i] = min(up, down)


@numba.njit(cache=True)
def patch_extrema(cells, values, vmax, vmin):
    """Extend ``vmax``/``vmin`` per node by the extrema of ``values`` over each cell's nodes.

    Every node of a cell receives the cell's extrema, so after all cells (and a cross-rank
    reduction) ``vmax[i]`` is the maximum over the patch of cells around ``i``.
    """
    for k in range(cells.shape[0]):
        hi = -np.inf
        lo = np.inf
        for a in range(4):
            v = values[cells[k, a]]
            hi = max(hi, v)
            lo = min(lo, v)
        for a in range(4):
            i = cells[k, a]
            vmax[i] = max(vmax[i], hi)
            vmin[i] = min(vmin[i], lo)


@numba.njit(cache=True)
def hydrostatic_candidate(h_i, z_i, h_j, z_j):
    """Depth that j's state allows at i, ``h_i + h*_ji - h*_ij`` (see :func:`depth_candidates`)."""
    top = max(z_i, z_j)
    return h_i + max(0.0, h_j + z_j - top) - max(0.0, h_i + z_i - top)


@numba.njit(cache=True)
def depth_candidates(cells, h, z, vmax, vmin):
    """Extend the depth bounds of every node by the hydrostatic candidates of its patch.

    For nodes ``i, j`` of a cell, with Audusse's reconstruction on the interface bed
    ``Z* = max(Z_i, Z_j)``, ``h*_ij = max(0, η_i - Z*)``, the depth that j's state allows at i
    is ``h_i + h*_ji - h*_ij``: ``η_j - Z_i`` where both sides are wet below Z* (the bound on
    the free surface, so a lake at rest over topography leaves no room and a smooth flow over
    a bump is not clipped), ``h_i`` where a dry bank stands above i (it brings nothing), and
    continuous in between — no wet/dry mask. ``j = i`` gives ``h_i``.
    """
    for k in range(cells.shape[0]):
        for a in range(4):
            i = cells[k, a]
            for b in range(4):
                j = cells[k, b]
                c = hydrostatic_candidate(h[i], z[i], h[j], z[j])
                vmax[i] = max(vmax[i], c)
                vmin[i] = min(vmin[i], c)


def limit_serial(
    cells: np.ndarray,
    aec: np.ndarray,
    u_low: np.ndarray,
    mass: np.ndarray,
    u_max: np.ndarray,
    u_min: np.ndarray,
) -> np.ndarray:
    """Limited nodal correction ``Σ_K (Σ_j f*_ij + μ*_i)`` for one scalar on one rank.

    Args:
        cells: (n, 4) node indices.
        aec: (n, 4) antidiffusive element contributions.
        u_low: Low-order nodal solution.
        mass: Lumped nodal mass.
        u_max: Upper bound per node (>= u_low).
        u_min: Lower bound per node (<= u_low).

    Returns:
        The correction per node (``m_i (u_i^{n+1} - u_i^L)``).
    """
    n = cells.shape[0]
    flux, source = np.empty((n, 6)), np.empty(n)
    split_pairs(np.ascontiguousarray(aec), flux, source)
    per_cell = np.empty((n, 4, 2))
    flux_sums(flux, source, per_cell)
    sums = np.zeros((u_low.shape[0], 2))
    np.add.at(sums, cells.ravel(), per_cell.reshape(-1, 2))
    rplus, rminus = zalesak_ratios(sums[:, 0], sums[:, 1], mass * (u_max - u_low),
                                   mass * (u_min - u_low))
    limited = np.empty((n, 4))
    limit_pairs(cells, flux, source, rplus, rminus, np.ones_like(u_low), limited)
    out = np.zeros_like(u_low)
    np.add.at(out, cells.ravel(), limited.ravel())
    return out


@numba.njit(cache=True)
def state_bounds(cells, h0, qx0, qy0, h1, qx1, qy1, z, hi, lo):
    """Patch bounds of two states in one pass over the cells (extends ``hi``/``lo`` (3, n)).

    Row 0: the hydrostatic depth candidates of :func:`depth_candidates` (the nodes' surfaces
    ``h + Z`` formed once per cell and state: the same operations); rows 1, 2: the extrema of
    the momenta; both states (old and low-order) count.
    """
    for k in range(cells.shape[0]):
        i0, i1, i2, i3 = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        z0, z1, z2, z3 = z[i0], z[i1], z[i2], z[i3]
        for s in range(2):
            h = h0 if s == 0 else h1
            qx = qx0 if s == 0 else qx1
            qy = qy0 if s == 0 else qy1
            mx_hi = max(max(qx[i0], qx[i1]), max(qx[i2], qx[i3]))
            mx_lo = min(min(qx[i0], qx[i1]), min(qx[i2], qx[i3]))
            my_hi = max(max(qy[i0], qy[i1]), max(qy[i2], qy[i3]))
            my_lo = min(min(qy[i0], qy[i1]), min(qy[i2], qy[i3]))
            ha0, ha1, ha2, ha3 = h[i0], h[i1], h[i2], h[i3]
            e0, e1, e2, e3 = ha0 + z0, ha1 + z1, ha2 + z2, ha3 + z3
            for a in range(4):
                i = i0 if a == 0 else (i1 if a == 1 else (i2 if a == 2 else i3))
                h_i = ha0 if a == 0 else (ha1 if a == 1 else (ha2 if a == 2 else ha3))
                z_i = z0 if a == 0 else (z1 if a == 1 else (z2 if a == 2 else z3))
                e_i = e0 if a == 0 else (e1 if a == 1 else (e2 if a == 2 else e3))
                c_hi, c_lo = hi[0, i], lo[0, i]
                for b in range(4):
                    z_j = z0 if b == 0 else (z1 if b == 1 else (z2 if b == 2 else z3))
                    e_j = e0 if b == 0 else (e1 if b == 1 else (e2 if b == 2 else e3))
                    top = max(z_i, z_j)
                    c = h_i + max(0.0, e_j - top) - max(0.0, e_i - top)
                    c_hi = max(c_hi, c)
                    c_lo = min(c_lo, c)
                hi[0, i], lo[0, i] = c_hi, c_lo
                hi[1, i] = max(hi[1, i], mx_hi)
                lo[1, i] = min(lo[1, i], mx_lo)
                hi[2, i] = max(hi[2, i], my_hi)
                lo[2, i] = min(lo[2, i], my_lo)


@numba.njit(cache=True)
def limit_pairs_sync(cells, flux, source, rplus, rminus, speed, cap, out):
    """Limit the pair fluxes of (h, hu, hv) together, per cell and node (``out[K, a, c]``).

    Each pair flux ``f_c`` first gets its own Zalesak factor ``α_c`` (as in
    :func:`limit_pairs`), then the common factor ``α = min_c (1 - (1 - α_c) s_c / s_max)``
    with the significance ``s_h = |f_h| U_ij``, ``s_q = |f_q|`` (``U_ij`` the larger flow
    speed ``|u|`` of the two nodes: the momentum the mass flux carries): a mass flux that
    carries the momentum flux caps it
    with its own factor and the reverse, so mass does not move without its momentum; a
    negligible flux (a uniform depth under a shear flow) does not cap the others. Where
    ``f_c`` changes sign its weight ``s_c / s_max`` vanishes, so ``α`` is continuous; the
    flux gets ``min(α, α_c) f_c`` and stays within its own bounds. Sources get their own
    factor. The momenta (fluxes and sources) are further capped by ``min(cap_i, cap_j)``
    (the thin-layer cap of :meth:`fem_runout.tg2.limiter.Limiter.thin_cap`).

    Args:
        cells: (n, 4) node indices.
        flux: (3, n, 6) pair fluxes.
        source: (3, n) per-cell sources.
        rplus: (3, n_nodes) ``R⁺`` per variable.
        rminus: (3, n_nodes) ``R⁻`` per variable.
        speed: (n_nodes,) flow speed ``|u|``.
        cap: (n_nodes,) cap of the momentum fluxes.
        out: (n, 4, 3) output.
    """
    for k in range(cells.shape[0]):
        # the cell's node values, read once (the stores to out could alias them for the
        # compiler): the same operations, the same bits
        n0, n1, n2, n3 = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        P0 = (rplus[0, n0], rplus[0, n1], rplus[0, n2], rplus[0, n3])
        P1 = (rplus[1, n0], rplus[1, n1], rplus[1, n2], rplus[1, n3])
        P2 = (rplus[2, n0], rplus[2, n1], rplus[2, n2], rplus[2, n3])
        M0 = (rminus[0, n0], rminus[0, n1], rminus[0, n2], rminus[0, n3])
        M1 = (rminus[1, n0], rminus[1, n1], rminus[1, n2], rminus[1, n3])
        M2 = (rminus[2, n0], rminus[2, n1], rminus[2, n2], rminus[2, n3])
        S = (speed[n0], speed[n1], speed[n2], speed[n3])
        CP = (cap[n0], cap[n1], cap[n2], cap[n3])
        s0, s1, s2 = source[0, k], source[1, k], source[2, k]
        for a in range(4):
            out[k, a, 0] = s0 * (P0[a] if s0 > 0.0 else M0[a])
            out[k, a, 1] = s1 * min(P1[a] if s1 > 0.0 else M1[a], CP[a])
            out[k, a, 2] = s2 * min(P2[a] if s2 > 0.0 else M2[a], CP[a])
        for p in range(6):
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            f0, f1, f2 = flux[0, k, p], flux[1, k, p], flux[2, k, p]
            a0 = _own_factor(f0, P0[a], M0[a], P0[b], M0[b])
            a1 = _own_factor(f1, P1[a], M1[a], P1[b], M1[b])
            a2 = _own_factor(f2, P2[a], M2[a], P2[b], M2[b])
            w0, w1, w2 = abs(f0) * max(S[a], S[b]), abs(f1), abs(f2)
            top = max(max(max(0.0, w0), w1), w2)
            common = 1.0
            if top > 0.0:
                common = min(common, 1.0 - (1.0 - a0) * (w0 / top))
                common = min(common, 1.0 - (1.0 - a1) * (w1 / top))
                common = min(common, 1.0 - (1.0 - a2) * (w2 / top))
            c_ij = min(CP[a], CP[b])
            g0 = f0 * min(common, a0)
            g1 = f1 * min(min(common, a1), c_ij)
            g2 = f2 * min(min(common, a2), c_ij)
            out[k, a, 0] += g0
            out[k, b, 0] -= g0
            out[k, a, 1] += g1
            out[k, b, 1] -= g1
            out[k, a, 2] += g2
            out[k, b, 2] -= g2
