"""TG2-PC's time-step bounds (``numerics.step_bound``): the depth's own bound and its steps."""

import math

import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.errors import CaseError
from fem_runout.references.inclined_dam_break import exact_front
from fem_runout.tg2.solver import build_tg2
from tests.tg2_helpers import case

COMM = MPI.COMM_SELF
G = 9.81


def _patch(froude: float, bound: str):
    """A uniform square of 0.1 m moving along x at ``froude``, in a dry flat 40 m box."""
    u = froude * math.sqrt(G * 0.1)
    inside = "where((abs(x - 20) < 8) * (abs(y - 20) < 8), 1, 0)"
    return load_case({
        "name": "patch", "gravity": G, "method": "tg2",
        "domain": {"extent": [0, 40, 0, 40], "cells": [40, 40], "boundary": "wall"},
        "terrain": {"elevation": 0.0},
        "initial": {"depth": f"0.1 * {inside}", "velocity": [f"{u} * {inside}", 0.0]},
        "time": {"end": 1.0}, "numerics": {"step_bound": bound},
    })


def _stable_dt(c) -> float:
    return float(build_tg2(c, COMM).transport.stable_dt())


def test_the_bounds_agree_where_nothing_moves():
    """A lake at rest (three bumps, two dry): ``β·u = 0``, so both bounds give the same step."""
    dts = [_stable_dt(case("lake_at_rest", f"numerics.step_bound={b}"))
           for b in ("conservative", "positivity")]
    print("lake at rest, dt:", dts)
    assert dts[0] == dts[1] and dts[0] > 0.0


@pytest.mark.parametrize("froude", [0.5, 20.0])
def test_positivity_bound_drops_the_advective_part(froude):
    """Uniform flow at a mesh's interior nodes: ``Σ_j β_ij = 0``, so the depth's bound is
    ``m / Σ_j d_ij`` and the conservative one ``m / Σ_j (d_ij + |β_ij·u|)``.

    With ``d_ij = |β_ij·u| + c |β_ij|`` and, on squares, ``Σ_j |β_ij| <= 2 Σ_j |β_ij,x|`` (the
    y-parts sum to the x-parts), the ratio ``1 + U B / (U B + c A)`` lies in
    ``[1 + 1/(1 + 2/Fr), 2)``.
    """
    cons, pos = (_stable_dt(_patch(froude, b)) for b in ("conservative", "positivity"))
    ratio = pos / cons
    print(f"Fr {froude}: dt {cons:.5g} -> {pos:.5g}, ratio {ratio:.4f}")
    assert 1.0 + 1.0 / (1.0 + 2.0 / froude) <= ratio < 2.0


def test_positivity_bound_on_the_inclined_dam_break():
    """Seed §4.1 with the depth's own bound: never negative, mass to round-off, at least half
    the steps of the conservative bound (each node's step is at most twice as long), fronts
    behind the exact dry-bed tip and closer to it on the finer grid. Each grid (2 and 1 m
    cells) runs on a strip of the 20 m channel three cells wide: the flow is y-invariant
    between the walls, so the strip has the channel's nodal depths, fronts and steps
    (``test_a_strip_of_the_channel_gives_the_channels_answer``, both methods)."""
    gaps, steps = [], {}
    for nx, dy in ((225, 2.0), (450, 1.0)):
        for bound in ("conservative", "positivity"):
            c = case("inclined_dam_break_450", f"domain.cells=[{nx},3]",
                     f"domain.extent=[0, 450, 0, {3 * dy}]", "time.end=11.0",
                     "output.every=5.5", f"numerics.step_bound={bound}")
            r = run(c, write=False, comm=COMM)
            steps[nx, bound] = r.steps
            if bound == "positivity":
                front = float(r.series["front_x"][-1])
                gaps.append(exact_front(11.0) - front)
                assert r.h.min() >= 0.0
                volume, gone = r.series["volume"], r.series["outflow"] + r.series["dried"]
                assert abs(volume[-1] + gone[-1] - volume[0]) <= 1e-12 * volume[0]
    print("steps", steps, "gaps to the exact tip [m]", gaps)
    for nx in (225, 450):
        assert 0.5 * steps[nx, "conservative"] <= steps[nx, "positivity"] \
            < steps[nx, "conservative"]
    assert 0.0 < gaps[1] < gaps[0]


def test_an_unknown_step_bound_is_rejected():
    with pytest.raises(CaseError, match="step_bound"):
        case("ritter", "numerics.step_bound=fast")
