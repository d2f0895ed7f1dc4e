"""Every benchmark reference: exact formulas checked, and each method measured at coarse levels.

The measured tests iterate over every implemented method, with the bounds stated per test
(from the TG2-PC numbers in docs/benchmarks.md, with a margin).
"""

import functools
import math

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.bench import ladders
from fem_runout.bench.suite_report import orders
from fem_runout.methods import method_names
from fem_runout.references import mangeney, radial, shear_decay, thacker, voellmy_sheet
from fem_runout.references.norms import crossing
from fem_runout.references.ritter import ritter_depth

COMM = MPI.COMM_SELF
METHODS = sorted(method_names())


def _ladder(fn, params, method):
    levels = [fn(p, method, COMM) for p in params]
    errors = [lv.error for lv in levels]
    name = getattr(fn, "func", fn).__name__
    print(f"{name} [{method}]: errors {errors}, orders {orders(errors)[1:]}")
    return levels, errors, [o for o in orders(errors) if o is not None]


# --- the formulas themselves ---------------------------------------------------------------


def test_radial_reference_conserves_mass_and_converges():
    """The hemisphere's 1D reference: exact volume, self-convergence, a converged front."""
    runs = [radial.radial_collapse(5.0, 1.2, 25.0, n) for n in (1000, 2000, 4000)]
    volume = 2.0 / 3.0 * math.pi * 5.0**3
    rs = np.linspace(0.0, 25.0, 50001)
    for r, h, _ in runs:
        assert abs(np.sum(2 * math.pi * r * (r[1] - r[0]) * h) / volume - 1) < 1e-12
        assert h.min() >= 0.0
    hs = [radial.sample(r, h, rs) for r, h, _ in runs]
    weight = 2 * math.pi * rs * (rs[1] - rs[0]) / volume
    diffs = [np.sum(weight * np.abs(a - b)) for a, b in zip(hs, hs[1:], strict=False)]
    fronts = [crossing(r, h, 1e-3) for r, h, _ in runs]
    print("radial reference: L1 differences", diffs, "fronts", fronts)
    assert diffs[1] < diffs[0] / 1.8  # converges (measured order 1.4)
    assert diffs[1] < 5e-4  # 100x below the 2D levels' errors (TG2-PC at 200²: 2.4e-2)
    assert abs(fronts[2] - fronts[1]) < 0.02  # m; a 2D cell at 200² is 0.25 m
    # it spread, but not faster than a planar dry-bed tip from the centre's 5 m (2 c0 t)
    assert 5.0 < fronts[2] < 5.0 + 2 * math.sqrt(9.81 * 5.0) * 1.2


def test_thacker_volume_is_constant_and_the_surface_is_a_rotating_plane():
    x, y = np.meshgrid(np.linspace(0, 4, 801), np.linspace(0, 4, 801))
    vols = [thacker.depth(x, y, t).sum() * (4 / 800) ** 2 for t in np.linspace(0, 4.5, 7)]
    exact = math.pi * thacker.A**2 * thacker.H0 / 2  # paraboloid cap of radius a, height h0
    assert np.allclose(vols, exact, rtol=2e-3)
    assert thacker.period() == pytest.approx(2 * math.pi / math.sqrt(2 * 9.81 * 0.1))
    assert thacker.depth(np.array([2.5]), np.array([2.0]), 0.0)[0] == pytest.approx(0.1)


def test_mangeney_is_ritter_in_the_accelerating_frame():
    x = np.linspace(0, 60, 601)
    t = 1.7
    shift = 0.5 * mangeney.acceleration(0.5, 0.2) * t * t
    h = mangeney.depth(x + shift, t, 1.0, 20.0, 0.5, 0.2)
    assert np.allclose(h, ritter_depth(x, t, 1.0, 20.0, 9.81), atol=1e-14)
    assert mangeney.depth(np.array([0.0]), t, 1.0, 20.0, 0.3, 0.3)[0] == 1.0


def test_voellmy_speed_solves_its_ode():
    t = np.linspace(0.1, 20, 200)
    u = np.array([voellmy_sheet.speed(s, 0.3, 0.1, 500.0, 1.0) for s in t])
    dudt = np.gradient(u, t, edge_order=2)
    rhs = 9.81 * 0.2 - 9.81 * u**2 / 500.0
    assert np.allclose(dudt, rhs, atol=2e-3)
    assert voellmy_sheet.terminal_speed(0.3, 0.1, 500.0, 1.0) == pytest.approx(10.0)


def test_shear_decay_rate_formula():
    assert shear_decay.decay_rate(500.0, 1000.0) == pytest.approx(0.5 * (2 * math.pi / 10) ** 2)


# --- measured, every implemented method ----------------------------------------------------
#
# Bounds per method where they differ (DAMPM numbers from docs/benchmarks.md, with a margin).


@pytest.mark.parametrize("method", METHODS)
def test_thacker_second_order_away_from_the_wet_dry_line(method):
    """L1 inside 0.2 m of the wet/dry line, 20-80 cells.

    TG2-PC 1.85e-2, 4.7e-3, 1.44e-3 (orders 1.99, 1.70); DAMPM 3.4e-3, 6.4e-4, 3.2e-4 (orders
    2.4, 1.0: first order claimed for the particle method only). Issue 13 asks TG2-PC to stay
    within 10 % of its error before the issue (1.362e-3 at 80 cells); without the shoreline's
    relaxed depth bound (``limiter.SHORE_SLACK``) it was 1.67e-3.
    """
    levels, errors, ords = _ladder(ladders.thacker, (20, 40, 80), method)
    assert errors[0] > errors[1] > errors[2]
    assert errors[-1] < (1.1 * 1.362e-3 if method == "tg2" else 2e-3)
    assert min(ords) > (1.6 if method == "tg2" else 0.8)
    assert levels[-1].extra["full_l1"] < 5e-3  # whole domain, wet/dry line included


@pytest.mark.parametrize("method", METHODS)
def test_mangeney_coulomb_incline_converges(method):
    """DAMPM 0.813, 0.487, 0.253 m² at 50, 100, 200 cells (orders 0.74, 0.95).

    TG2-PC with the edge-based limiter (issue 13): 0.213, 0.162, 0.094, 0.050, 0.026 at 50 to
    800 cells (orders 0.39, 0.78, 0.90, 0.93): smaller errors than before on every level
    (0.471, 0.257, 0.134 at 50–200), the coarsest one pre-asymptotic, so its ladder starts
    at 200 cells. Front (last node with h > 1e-3) at 200 cells: DAMPM 36.0 m, exact 38.4.
    """
    cells = (200, 400, 800) if method == "tg2" else (50, 100, 200)
    levels, errors, ords = _ladder(ladders.mangeney, cells, method)
    assert errors[0] > errors[1] > errors[2]
    bound, order = (0.15, 0.8) if method == "tg2" else (0.3, 0.65)
    assert min(ords) > order and errors[-1] < bound
    assert abs(levels[-1].extra["front"] - levels[-1].extra["exact_front"]) < 2.5


@pytest.mark.parametrize("method", METHODS)
def test_ritter_converges_first_order(method):
    """TG2-PC first order below 0.16 m² at 400 cells; DAMPM 0.816, 0.438, 0.227 (0.90, 0.95)."""
    _, errors, ords = _ladder(ladders.ritter, (100, 200, 400), method)
    bound, order = (0.16, 0.9) if method == "tg2" else (0.25, 0.85)
    assert min(ords) > order and errors[-1] < bound


@pytest.mark.parametrize("method", METHODS)
def test_voellmy_sheet_speed(method):
    """Relative speed error at dx = 1 m below 1e-4: a second-order friction step.

    The sheet has no gradients, so its error is the time integration of the friction ODE
    (``FrictionLaw.integrate`` inside Strang's splitting). With one backward-Euler solve per
    step it was first order: 5.8e-3 (TG2-PC, Strang, 300 steps) and 1.7e-4 (DAMPM, Lie, 400
    steps), which the ODE alone reproduces (3.6e-3, 1.7e-4 at 400 steps); now 1.7e-6 and 8.7e-7.
    """
    _, errors, _ = _ladder(ladders.voellmy_sheet, (50, 400), method)
    assert errors[1] < errors[0] and errors[1] < 1e-4


@pytest.mark.parametrize("method", METHODS)
def test_shear_decay_converges(method):
    """Relative rate error: TG2-PC 2.3e-2, 6.1e-3, 1.6e-3 (orders 1.91, 1.92); DAMPM 0.45,
    0.18, 0.078 (orders 1.34, 1.19: the PIC share of the velocity update damps the mode)."""
    _, errors, ords = _ladder(ladders.shear_decay, (10, 20, 40), method)
    bound, order = (3e-3, 1.8) if method == "tg2" else (0.1, 1.0)
    assert min(ords) > order and errors[-1] < bound


@pytest.mark.parametrize("method", METHODS)
def test_inclined_dam_break_front_error_shrinks(method):
    """Relative front error at 11 s: TG2-PC 0.070, 0.055, DAMPM 0.085, 0.057 (dx = 2, 1 m).

    On a strip of the channel three cells wide (the same cells, fronts and steps as the whole
    20 m channel, checked for both
    methods by ``test_a_strip_of_the_channel_gives_the_channels_answer``)."""
    _, errors, _ = _ladder(functools.partial(ladders.dam_break, rows=3), (225, 450), method)
    assert errors[1] < errors[0] < 0.1


@pytest.mark.parametrize("method", METHODS)
def test_hemisphere_and_lake_at_rest(method):
    """Hemisphere at 50² and 100²: L1 against the radial reference falls, fronts symmetric."""
    levels, errors, _ = _ladder(ladders.hemisphere, (50, 100), method)
    assert errors[1] < errors[0] and errors[1] < 0.1  # relative L1 of h
    for hemi, dx in zip(levels, (1.0, 0.5), strict=True):
        assert hemi.extra["spread"] <= math.sqrt(2) * dx + 1e-9  # one diagonal cell
        assert hemi.extra["front_error"] < 3 * dx  # the front within 3 cells of the reference
        r_x, r_y, r_mx = (hemi.extra[k] for k in ("r_x", "r_y", "r_mx"))
        assert r_x > 5.0 and math.isclose(r_x, r_y, rel_tol=1e-12)  # symmetric to round-off
        assert math.isclose(r_x, r_mx, rel_tol=1e-12)
    lake = ladders.lake_at_rest(25, method, COMM)
    assert max(lake.extra.values()) <= 1e-12, lake.extra
