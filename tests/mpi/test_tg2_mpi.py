"""TG2-PC under MPI: well-balancing on 2 ranks and results independent of the rank count."""

from mpi4py import MPI

from fem_runout.api import run
from tests.tg2_helpers import assert_same_on_ranks, case, lake_errors

WORLD = MPI.COMM_WORLD


def test_lake_at_rest_is_exact_in_parallel():
    result = run(case("lake_at_rest"), write=False, comm=WORLD)
    if WORLD.rank == 0:
        errors = lake_errors(result)
        print(f"lake at rest on {WORLD.size} ranks:", errors)
        for name, (e1, einf) in errors.items():
            assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)


def _compare(c, tol=0.0):
    """TG2-PC gives the same bits on any rank count (``fem_runout.cellsum``)."""
    assert_same_on_ranks(c, WORLD, tol)


def test_same_result_on_one_and_two_ranks_open_slope():
    _compare(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                  "output.every=1.0"))


def test_same_result_on_one_and_two_ranks_closed_box():
    _compare(case("hemisphere", "domain.extent=[15,35,15,35]", "domain.cells=[30,30]",
                  "domain.boundary=wall", "time.end=2.0", "output.every=1.0"))


FULL = ("material.friction={law: voellmy, phi_deg: 26, xi: 500}",
        "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}")


def test_lake_at_rest_with_friction_and_rheology_in_parallel():
    result = run(case("lake_at_rest", *FULL), write=False, comm=WORLD)
    if WORLD.rank == 0:
        for name, (e1, einf) in lake_errors(result).items():
            assert e1 <= 1e-12 and einf <= 1e-12, (name, e1, einf)


def test_voellmy_dam_break_same_on_one_and_two_ranks():
    _compare(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                  "output.every=1.0", "material.friction={law: voellmy, phi_deg: 26, xi: 500}"))


def test_bingham_voellmy_dam_break_same_on_one_and_two_ranks():
    _compare(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=2.0",
                  "output.every=1.0", *FULL))


def test_slope_form_with_curvature_same_on_one_and_two_ranks():
    """Slope-consistent form (issue 14) on a curved bed: nodal ∇Z and Hessian by cell sums."""
    _compare(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                  "output.every=1.0", "model.form=slope", "model.curvature=true",
                  "terrain.elevation=100 - x/3 + 0.002*(x - 60)**2 + 0.5*sin(y/4)",
                  "material.friction={law: voellmy, mu: 0.2, xi: 500}"))


def test_positivity_step_bound_same_on_one_and_two_ranks():
    """``numerics.step_bound: positivity`` (the longer steps) keeps the rank-independent bits."""
    _compare(case("inclined_dam_break", "domain.cells=[120,8]", "time.end=3.0",
                  "output.every=1.0", "numerics.step_bound=positivity",
                  "material.friction={law: voellmy, phi_deg: 26, xi: 500}"))
