"""The slope-consistent form (issue 14): geometry, friction on the bed, exact references.

Bounds come from the exact solutions (``fem_runout/references/slope.py``) and the observed
order of convergence: a coarse level within a stated error, and the error falling under
refinement at no less than first order with margin (ratio <= 0.7 per halving of the cells).
"""

import math

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.bench import ladders
from fem_runout.config import load_case
from fem_runout.errors import CaseError
from fem_runout.mesh import build_discretization
from fem_runout.methods import method_names
from fem_runout.physics.friction import Coulomb, Voellmy
from fem_runout.physics.slope import BedFrame, slope_geometry
from tests.tg2_helpers import case, lake_errors

COMM = MPI.COMM_SELF
METHODS = method_names()
THETA = math.radians(35.0)


def _plane_frame(n: int, slope: float = math.tan(THETA)) -> BedFrame:
    grad = np.tile([-slope, 0.0], (n, 1))
    cos = np.full(n, 1.0 / math.sqrt(1.0 + slope * slope))
    return BedFrame(grad, cos, 9.81 * cos)


def test_geometry_of_a_plane_and_a_paraboloid():
    disc = build_discretization(COMM, (0.0, 40.0, 0.0, 20.0), (20, 10),
                                {s: "wall" for s in ("left", "right", "bottom", "top")})
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    plane = slope_geometry(disc, 3.0 - 0.7 * x + 0.2 * y, 9.81)
    np.testing.assert_allclose(plane.grad, np.tile([-0.7, 0.2], (x.size, 1)), atol=1e-13)
    np.testing.assert_allclose(plane.hess, 0.0, atol=1e-13)
    np.testing.assert_allclose(plane.cos2, 1.0 / (1.0 + 0.49 + 0.04), rtol=1e-14)
    bowl = slope_geometry(disc, 0.01 * (x - 20.0) ** 2, 9.81)
    inner = (x > 4.0) & (x < 36.0)  # two nodes from the sides (one-sided projections there)
    np.testing.assert_allclose(bowl.hess[inner, 0], 0.02, rtol=1e-12)
    np.testing.assert_allclose(bowl.hess[:, 1:], 0.0, atol=1e-13)
    # G of a flow along a concave bed: cos²θ (g + u² Z_xx)
    u = np.full(x.size, 10.0)
    expected = bowl.cos2 * (9.81 + 100.0 * bowl.hess[:, 0])
    np.testing.assert_allclose(bowl.pressure_gravity(u, 0 * u)[inner], expected[inner])


def test_friction_on_the_bed_of_a_plane():
    """Downslope motion: Coulomb μ g cos²θ, drag g u²/(ξ cos²θ) on the horizontal momentum."""
    n = 4
    bed = _plane_frame(n)
    c2 = math.cos(THETA) ** 2
    law = Voellmy(0.2, 500.0, 9.81, gamma=1e-3)
    h, u = np.full(n, 1.2), np.array([3.0, 5.0, 8.0, 13.0])
    rx, ry = law.rate(h, h * u, 0 * u, bed)
    expected = -(9.81 * c2 * 0.2 * h + 9.81 * u * u / (500.0 * c2))
    np.testing.assert_allclose(rx, expected, rtol=1e-13)
    assert np.all(ry == 0.0)
    # Coulomb yield on the bed: a layer at rest on 35° holds with μ = 0.75 > tan 35° = 0.70
    # against one step of gravity along the slope, G h S dt = g cos²θ tan θ h dt
    dt = 0.1
    push = 9.81 * c2 * math.tan(THETA) * h * dt
    for mu, held in ((0.75, True), (0.65, False)):
        qx, _ = Coulomb(mu, 9.81).implicit_update(h, 0 * h, 0 * h, push, 0 * h, dt, bed)
        assert np.all(qx == 0.0) == held
    # the Voellmy terminal state is a fixed point of the implicit update
    hn, mu, xi = 1.0, 0.2, 500.0
    big_u = math.sqrt(xi * hn * (math.sin(THETA) - mu * math.cos(THETA)))
    hv, uh = np.full(n, hn / math.cos(THETA)), np.full(n, big_u * math.cos(THETA))
    drive = 9.81 * c2 * math.tan(THETA) * hv * dt
    q, _ = Voellmy(mu, xi).implicit_update(hv, hv * uh, 0 * hv, hv * uh + drive, 0 * hv, dt,
                                           bed)
    np.testing.assert_allclose(q, hv * uh, rtol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_lake_at_rest_is_exact_in_the_slope_form(method):
    """Seed §4.2 in the slope form (cos²θ and curvature on the bumps): errors <= 1e-12."""
    result = run(case("lake_at_rest", f"method={method}", "model.form=slope",
                      "model.curvature=true", "time.end=0.5"), write=False, comm=COMM)
    for name, (e1, einf) in lake_errors(result).items():
        assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)


def test_curvature_needs_the_slope_form():
    with pytest.raises(CaseError, match="model.curvature"):
        case("ritter", "model.curvature=true")
    assert not case("ritter").slope_form and case("ritter", "model.form=slope").slope_form


def test_curvature_is_on_by_default_with_the_slope_form():
    """As com1DFA (``curvAccInFriction = 1``) and RAMMS; off in the horizontal form."""
    assert not case("ritter").curvature
    assert case("ritter", "model.form=slope").curvature
    assert not case("ritter", "model.form=slope", "model.curvature=false").curvature
    assert case("ritter", "model.form=slope", "model.curvature=true").curvature


@pytest.mark.parametrize("method", METHODS)
def test_voellmy_sheet_reaches_the_slope_terminal_speed(method):
    """U(t) of a sheet on 35° (U_∞ = 14.3 m/s): TG2-PC first order, DAMPM within 2e-3."""
    coarse = ladders.voellmy_slope(100, method, COMM)
    fine = ladders.voellmy_slope(200, method, COMM)
    print(method, coarse.error, fine.error)
    if method == "tg2":
        assert coarse.error <= 0.06 and fine.error <= 0.7 * coarse.error
    else:
        assert coarse.error <= 2e-3 and fine.error <= 2e-3


@pytest.mark.parametrize("method", METHODS)
def test_a_coulomb_block_stops_on_the_energy_line(method):
    """35° onto a flat run-out, μ = 0.3: tan α of the centre of mass within 3 % of μ."""
    level = ladders.energy_line(200, method, COMM)
    print(method, level.extra)
    assert level.error <= 0.03


@pytest.mark.parametrize("method", METHODS)
def test_mangeney_dam_break_on_30_degrees_converges(method):
    """L1 of h against the exact slope-form solution: within bounds, falling under refinement."""
    coarse = ladders.mangeney_slope(120, method, COMM)
    fine = ladders.mangeney_slope(240, method, COMM)
    print(method, coarse.error, fine.error, fine.extra)
    assert fine.error <= 0.7 * coarse.error
    assert fine.error <= (0.15 if method == "tg2" else 0.4)


def test_dem_cases_default_to_the_slope_form(tmp_path):
    import shapely

    from tests.terrain_helpers import dem_case, plane, write_dem, write_polygons

    dem = write_dem(tmp_path / "dem.tif", plane())
    write_polygons(tmp_path / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    c = load_case(dem_case(dem))
    assert c.slope_form and not load_case(dem_case(dem, model={"form": "horizontal"})).slope_form
