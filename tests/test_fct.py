"""The Zalesak FCT limiter as a unit, on cell–node arrays."""

import numpy as np
import pytest

from fem_runout.health import state_flag
from fem_runout.tg2 import fct, limiter


def _strip(n_cells: int) -> np.ndarray:
    """A 1-cell-wide strip of quads: cell k has nodes (k, k+1, k+n+1, k+n+2) style indices."""
    n = n_cells + 1
    return np.array([[k, k + 1, n + k, n + k + 1] for k in range(n_cells)], dtype=np.int64)


def _random_problem(seed: int, n_cells: int = 40):
    rng = np.random.default_rng(seed)
    cells = _strip(n_cells)
    nn = 2 * (n_cells + 1)
    u_low = rng.uniform(0.0, 2.0, nn)
    mass = rng.uniform(0.5, 1.5, nn)
    raw = rng.normal(size=(n_cells, 4))
    aec = raw - raw.mean(axis=1, keepdims=True)  # each cell's contributions sum to zero
    return cells, aec, u_low, mass


def _bounds(cells, u_low):
    nn = u_low.shape[0]
    vmax, vmin = np.full(nn, -np.inf), np.full(nn, np.inf)
    fct.patch_extrema(cells, u_low, vmax, vmin)
    return vmax, vmin


@pytest.mark.parametrize("seed", range(5))
def test_limited_update_stays_in_bounds_and_conserves(seed):
    cells, aec, u_low, mass = _random_problem(seed)
    vmax, vmin = _bounds(cells, u_low)
    corr = fct.limit_serial(cells, aec, u_low, mass, vmax, vmin)
    u_new = u_low + corr / mass
    assert np.all(u_new <= vmax + 1e-14) and np.all(u_new >= vmin - 1e-14)
    # conservation: Σ m u is unchanged by the limited antidiffusion
    assert abs(np.sum(mass * u_new) - np.sum(mass * u_low)) < 1e-12
    # the limiter does something on random data: the full correction leaves the bounds
    full = np.zeros_like(u_low)
    np.add.at(full, cells.ravel(), aec.ravel())
    assert np.any((u_low + full / mass > vmax) | (u_low + full / mass < vmin))
    assert np.abs(corr - full).max() > 1e-3


def test_full_correction_when_bounds_are_loose():
    cells, aec, u_low, mass = _random_problem(7)
    big = np.full_like(u_low, 1e9)
    corr = fct.limit_serial(cells, aec, u_low, mass, u_low + big, u_low - big)
    full = np.zeros_like(u_low)
    np.add.at(full, cells.ravel(), aec.ravel())
    np.testing.assert_allclose(corr, full, rtol=0, atol=1e-14)


def test_no_correction_with_tight_bounds():
    cells = _strip(1)
    u_low = np.array([1.0, 1.0, 1.0, 1.0])
    aec = np.array([[1.0, -1.0, 0.5, -0.5]])
    corr = fct.limit_serial(cells, aec, u_low, np.ones(4), u_low, u_low)
    np.testing.assert_array_equal(corr, 0.0)


@pytest.mark.parametrize("seed", range(3))
def test_limited_correction_is_lipschitz_in_the_data(seed):
    """A perturbation of size ε moves the correction by O(ε), also through sign changes.

    Contributions of round-off size (1e-17) whose signs flip must not switch the correction
    of the other nodes (the element-based factor α_K = min_i R_i did, by O(1)).
    """
    cells, aec, u_low, mass = _random_problem(seed)
    aec[::3, 1] = 1e-17 * (1 if seed % 2 else -1)  # tiny entries at many nodes
    aec -= aec.mean(axis=1, keepdims=True)
    vmax, vmin = _bounds(cells, u_low)
    base = fct.limit_serial(cells, aec, u_low, mass, vmax, vmin)
    rng = np.random.default_rng(100 + seed)
    for eps in (1e-14, 1e-10):
        d_aec = eps * rng.normal(size=aec.shape)
        d_aec -= d_aec.mean(axis=1, keepdims=True)
        d_u = eps * rng.normal(size=u_low.shape)
        moved = fct.limit_serial(cells, aec + d_aec, u_low + d_u, mass, vmax + d_u, vmin + d_u)
        assert np.abs(moved - base).max() <= 50.0 * eps, eps


def test_hydrostatic_depth_bounds_lake_and_dry_bank():
    """Lake at rest over a step: no room for the depth; a dry bank adds no room."""
    cells = _strip(2)
    z = np.array([0.0, 0.5, 2.0, 0.0, 0.5, 2.0])
    h = np.array([1.0, 0.5, 0.0, 1.0, 0.5, 0.0])  # η = 1 where wet; node 2 dry above it
    hi, lo = np.full(6, -np.inf), np.full(6, np.inf)
    fct.depth_candidates(cells, h, z, hi, lo)
    np.testing.assert_allclose(hi, h)
    np.testing.assert_allclose(lo, h)


def test_ratios_exact_values():
    rp, rm = fct.zalesak_ratios(
        np.array([2.0, 0.0, 1.0]), np.array([-4.0, -1.0, 0.0]),
        np.array([1.0, 5.0, 3.0]), np.array([-1.0, -0.25, -1.0]),
    )
    np.testing.assert_allclose(rp, [0.5, 1.0, 1.0])
    np.testing.assert_allclose(rm, [0.25, 0.25, 1.0])


def _bits(a):
    return np.ascontiguousarray(a).view(np.int64)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fused_pair_split_has_the_bits_of_the_per_variable_passes(seed):
    """split_flux_sums (one pass for h, hu, hv) = split_pairs + flux_sums per variable, bit for
    bit (signed zeros included), on contributions with zeros, -0.0 and ties."""
    rng = np.random.default_rng(seed)
    n = 4000
    aec = rng.normal(size=(n, 4, 3)) * (rng.random((n, 4, 3)) < 0.7)
    aec[::7] = 0.0
    aec[::11, 0, 1] = -0.0
    aec[::13, 2] = aec[::13, 1]  # equal contributions: zero pair fluxes
    flux, source, per = np.empty((3, n, 6)), np.empty((3, n)), np.empty((n, 4, 6))
    for c in range(3):
        fct.split_pairs(np.ascontiguousarray(aec[:, :, c]), flux[c], source[c])
        fct.flux_sums(flux[c], source[c], per[:, :, 2 * c:2 * c + 2])
    fused = np.empty((3, n, 6)), np.empty((3, n)), np.empty((n, 4, 6))
    fct.split_flux_sums(aec, *fused)
    for ref, got in zip((flux, source, per), fused, strict=True):
        assert np.array_equal(_bits(ref), _bits(got))
    total = per[:, :, 0::2].sum(axis=1) + per[:, :, 1::2].sum(axis=1)  # fluxes cancel
    assert np.abs(total - 4.0 * source.T).max() < 1e-12


def test_bounds_from_extrema_follow_the_array_formulas():
    """The per-node kernel gives the formulas of Limiter.finish_bounds, bit for bit: momentum
    slack, shoreline slack ramped by the patch's shallowest depth, h >= 0, and ±inf extrema
    (nodes without active cells) leave the low-order state as both bounds."""
    rng = np.random.default_rng(3)
    n, thin, ms, ss = 500, 1e-3, limiter.MOMENTUM_SLACK, limiter.SHORE_SLACK
    q_low = rng.normal(size=(n, 3))
    q_low[:, 0] = np.abs(q_low[:, 0]) * (rng.random(n) < 0.8)
    hi = q_low.T + rng.random((3, n))
    lo = q_low.T - rng.random((3, n))
    near = np.abs(rng.normal(size=n)) * 2e-3
    ext = np.vstack([hi, -lo, near + 1.0, -near, rng.random(n)])
    ext[:8, :20] = -np.inf  # no active cell around these nodes
    upper, lower = np.empty((n, 3)), np.empty((n, 3))
    limiter.bounds_from_extrema(ext.copy(), q_low, thin, ms, ss, upper, lower)
    h_hi, h_lo, nr = ext[0:3].copy(), -ext[3:6], -ext[7]
    with np.errstate(invalid="ignore"):
        slack = ms * (h_hi[1:] - h_lo[1:])
        h_hi[1:] += slack
        h_lo[1:] -= slack
        shore = np.clip(1.0 - nr / thin, 0.0, 1.0)
        spread = np.where(h_hi[0] > h_lo[0], h_hi[0] - h_lo[0], 0.0)
    h_hi[0] += ss * shore * np.minimum(spread, np.maximum(q_low[:, 0], 0.0))
    h_lo[0] = np.maximum(h_lo[0], 0.0)
    assert np.array_equal(upper, np.maximum(h_hi.T, q_low))
    assert np.array_equal(lower, np.minimum(h_lo.T, q_low))
    assert np.array_equal(upper[:20], q_low[:20]) and np.array_equal(lower[:20], q_low[:20])
    assert (upper >= q_low).all() and (lower <= q_low).all() and (lower[:, 0] <= 0.0).any()


def test_state_flag_codes():
    """0 for a good state, 1 for a negative depth, 2 for any non-finite value (it wins over a
    negative depth before it); only the first n nodes count."""
    h, hu, hv = np.ones(10), np.zeros(10), np.zeros(10)
    assert state_flag(h, hu, hv, 10) == 0
    h[3] = -1e-300
    assert state_flag(h, hu, hv, 10) == 1
    hv[7] = np.inf
    assert state_flag(h, hu, hv, 10) == 2
    assert state_flag(h, hu, hv, 7) == 1
    h[3], hv[7], hu[9] = 1.0, 0.0, np.nan
    assert state_flag(h, hu, hv, 9) == 0
    assert state_flag(h, hu, hv, 10) == 2


def test_state_bounds_are_the_hydrostatic_candidates_and_momentum_extrema_of_both_states():
    """state_bounds (one pass, each node's surface formed once per cell) = depth_candidates
    and the momenta's patch extrema of the two states, bit for bit; dry nodes and steps in the
    bed included."""
    rng = np.random.default_rng(5)
    n_nodes, n = 300, 400
    cells = rng.integers(0, n_nodes, size=(n, 4))
    z = 100.0 * rng.random(n_nodes)
    states = []
    for _ in range(2):
        h = rng.random(n_nodes) * (rng.random(n_nodes) < 0.6)
        states.append((h, rng.normal(size=n_nodes), rng.normal(size=n_nodes)))
    hi, lo = np.full((3, n_nodes), -np.inf), np.full((3, n_nodes), np.inf)
    fct.state_bounds(cells, *states[0], *states[1], z, hi, lo)
    ref_hi, ref_lo = np.full((3, n_nodes), -np.inf), np.full((3, n_nodes), np.inf)
    for h, qx, qy in states:
        fct.depth_candidates(cells, h, z, ref_hi[0], ref_lo[0])
        fct.patch_extrema(cells, qx, ref_hi[1], ref_lo[1])
        fct.patch_extrema(cells, qy, ref_hi[2], ref_lo[2])
    assert np.array_equal(_bits(hi), _bits(ref_hi)) and np.array_equal(_bits(lo), _bits(ref_lo))
    wet = np.isfinite(hi[0])
    assert wet.sum() > 200 and (lo[0][wet] <= hi[0][wet]).all()
