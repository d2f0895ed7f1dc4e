"""The bed's curvature at a physical scale (``model.curvature_scale``; physics/bed_filter)."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.config.loader import load_case
from fem_runout.errors import CaseError
from fem_runout.physics.bed_filter import heat_smoothed
from fem_runout.physics.slope import slope_geometry
from fem_runout.problem import discretize
from tests.quad_helpers import distorted_rectangle

EXTENT = (0.0, 400.0, 0.0, 200.0)
SIDES = {s: "open" for s in ("left", "right", "bottom", "top")}
SCALE = 10.0
LONG, SHORT = 2 * np.pi / 200.0, 2 * np.pi / 20.0  # wavenumbers [1/m]


def _grid(cells: tuple[int, int]):
    case = load_case({"name": "t", "domain": {"extent": list(EXTENT), "cells": list(cells)},
                      "terrain": {"elevation": "0"}, "initial": {"depth": "0"},
                      "time": {"end": 1}, "model": {"form": "slope"}})
    return discretize(case, MPI.COMM_SELF)


def _deep(disc, margin: float) -> np.ndarray:
    x, y = disc.coords[:, 0], disc.coords[:, 1]
    return (x > margin) & (x < EXTENT[1] - margin) & (y > margin) & (y < EXTENT[3] - margin)


def test_a_quadratic_bed_keeps_its_hessian_and_shifts_by_the_heat_flow():
    """Heat flow adds ``t ∇²Z`` (``t = ℓ²/2``) to a quadratic bed: its Hessian is unchanged."""
    disc = _grid((80, 40))
    x, y = disc.coords[:, 0] - 200.0, disc.coords[:, 1] - 100.0
    z = 0.002 * x * x + 0.003 * x * y - 0.001 * y * y - 0.4 * x
    smooth = heat_smoothed(disc, z, SCALE)
    deep = _deep(disc, 8 * SCALE)  # the sides' natural condition reaches a few ℓ
    laplacian = 2 * 0.002 - 2 * 0.001
    np.testing.assert_allclose((smooth - z)[deep], 0.5 * SCALE**2 * laplacian, rtol=1e-9)
    plain, scaled = (slope_geometry(disc, z, 9.81, True, s) for s in (None, SCALE))
    np.testing.assert_allclose(scaled.hess[deep], plain.hess[deep], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(scaled.grad, plain.grad)  # the slope stays the bed's


@pytest.mark.parametrize("mesh", ["grid 5 m", "grid 2.5 m", "jittered 5 m"])
def test_the_curvature_follows_the_scale_not_the_cells(mesh):
    """A 200 m wave keeps its curvature, a 20 m one loses it, on any mesh of the terrain.

    The Gaussian of standard deviation ``ℓ`` multiplies a wave's Hessian by
    ``exp(-k² ℓ² / 2)``: 0.976 at 200 m, 7e-3 at 20 m (ℓ = 10 m).
    """
    disc = {"grid 5 m": lambda: _grid((80, 40)), "grid 2.5 m": lambda: _grid((160, 80)),
            "jittered 5 m": lambda: distorted_rectangle(MPI.COMM_SELF, EXTENT, (80, 40), SIDES,
                                                        amp=0.2, seed=5)}[mesh]()
    x = disc.coords[:, 0]
    deep = _deep(disc, 6 * SCALE)

    def curvature(k: float, scale: float | None = SCALE) -> np.ndarray:
        return slope_geometry(disc, 2.0 * np.sin(k * x), 9.81, True, scale).hess[deep, 0]

    def error(scale: float | None) -> float:
        damping = np.exp(-0.5 * (LONG * scale) ** 2) if scale else 1.0
        exact = -2.0 * LONG**2 * damping * np.sin(LONG * x[deep])
        return float(np.abs(curvature(LONG, scale) - exact).max()) / (2.0 * LONG**2)

    # the 200 m wave: the smoothing adds at most 1 % of its curvature to the Q1 Hessian's own
    # error (below 1 % on the grids, about 5 % on the jittered mesh, with or without it)
    assert error(SCALE) <= error(None) + 0.01
    # the 20 m wave: raw curvature 2 k² = 0.2 m⁻¹ (8 g at 50 m/s), below 2 % of it
    raw = np.abs(slope_geometry(disc, 2.0 * np.sin(SHORT * x), 9.81, True).hess[deep, 0]).max()
    assert np.abs(curvature(SHORT)).max() <= 0.02 * raw


def test_curvature_scale_is_validated():
    base = {"name": "t", "domain": {"extent": [0, 10, 0, 10], "cells": [4, 4]},
            "terrain": {"elevation": "0"}, "initial": {"depth": "0"}, "time": {"end": 1}}
    with pytest.raises(CaseError, match=r"model.curvature_scale.*model.form: slope"):
        load_case({**base, "model": {"curvature_scale": 10}})
    with pytest.raises(CaseError, match=r"model.curvature_scale"):
        load_case({**base, "model": {"form": "slope", "curvature_scale": -1}})
    case = load_case({**base, "model": {"form": "slope", "curvature_scale": 10}})
    assert case.model.curvature_scale == 10
