"""The Zalesak FCT limiter as a unit, on cell–node arrays."""

import numpy as np
import pytest

from fem_runout.tg2 import fct


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
    fct.patch_extrema(cells, u_low, np.ones(nn, dtype=np.bool_), vmax, vmin)
    return vmax, vmin


@pytest.mark.parametrize("seed", range(5))
def test_limited_update_stays_in_bounds_and_conserves(seed):
    cells, aec, u_low, mass = _random_problem(seed)
    vmax, vmin = _bounds(cells, u_low)
    alpha = fct.limit_serial(cells, aec, u_low, mass, vmax, vmin)
    assert alpha.min() >= 0.0 and alpha.max() <= 1.0
    corr = np.zeros((u_low.shape[0], 1))
    fct.scatter_cells(cells, aec[:, :, None], alpha, corr)
    u_new = u_low + corr[:, 0] / mass
    assert np.all(u_new <= vmax + 1e-14) and np.all(u_new >= vmin - 1e-14)
    # conservation: Σ m u is unchanged by the limited antidiffusion
    assert abs(np.sum(mass * u_new) - np.sum(mass * u_low)) < 1e-12
    # the limiter does something on random data
    assert alpha.min() < 1.0


def test_alpha_is_one_when_bounds_are_loose():
    cells, aec, u_low, mass = _random_problem(7)
    big = np.full_like(u_low, 1e9)
    alpha = fct.limit_serial(cells, aec, u_low, mass, u_low + big, u_low - big)
    np.testing.assert_array_equal(alpha, 1.0)


def test_alpha_is_zero_at_an_extremum_with_tight_bounds():
    cells = _strip(1)
    u_low = np.array([1.0, 1.0, 1.0, 1.0])
    aec = np.array([[1.0, -1.0, 0.5, -0.5]])
    alpha = fct.limit_serial(cells, aec, u_low, np.ones(4), u_low, u_low)
    assert alpha[0] == 0.0


def test_ratios_exact_values():
    rp, rm = fct.zalesak_ratios(
        np.array([2.0, 0.0, 1.0]), np.array([-4.0, -1.0, 0.0]),
        np.array([1.0, 5.0, 3.0]), np.array([-1.0, -0.25, -1.0]),
    )
    np.testing.assert_allclose(rp, [0.5, 1.0, 1.0])
    np.testing.assert_allclose(rm, [0.25, 0.25, 1.0])
