"""TG2-PC's gated consistent-mass correction (fem_runout/tg2/mass_correction.py)."""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.mesh import element_masses
from fem_runout.references.norms import nodal_weights
from fem_runout.references.radial import hemisphere_errors
from fem_runout.tg2.mass_correction import add_correction, sensor_sums
from tests.tg2_helpers import CASES

COMM = MPI.COMM_SELF
SQUARE = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]])  # basix's Q1 order


def test_element_mass_of_a_square_is_the_exact_q1_matrix():
    """``∫ φ_a φ_b`` on a 2 m square: |K|/36 (4, 2, 2, 1) pattern, row sums |K|/4."""
    mass = element_masses(np.array([[0, 1, 2, 3]]), SQUARE)[0]
    exact = 4.0 / 36.0 * np.array([[4, 2, 2, 1], [2, 4, 1, 2], [2, 1, 4, 2], [1, 2, 2, 4]])
    assert np.allclose(mass, exact, rtol=0, atol=1e-15)
    assert np.allclose(mass.sum(axis=1), 1.0, rtol=0, atol=1e-15)


def _two_cells(dq_fn):
    """Two 2 m cells side by side (nodes 0..5), element masses and nodal increments."""
    coords = np.array([[0, 0], [2, 0], [4, 0], [0, 2], [2, 2], [4, 2]], dtype=float)
    cells = np.array([[0, 1, 3, 4], [1, 2, 4, 5]])
    return cells, element_masses(cells, coords), dq_fn(coords)


def test_correction_conserves_and_vanishes_on_uniform_increments():
    """Each cell's contributions sum to zero; a uniform increment gives none."""
    rng = np.random.default_rng(3)
    cells, mc, dq = _two_cells(lambda x: rng.normal(size=(x.shape[0], 3)))
    aec = np.zeros((2, 4, 3))
    add_correction(cells, mc, dq, np.zeros(6), aec)
    assert np.abs(aec).max() > 0.1
    assert np.abs(aec.sum(axis=1)).max() < 1e-15
    aec[:] = 0.0
    add_correction(cells, mc, np.ones((6, 3)), np.zeros(6), aec)
    assert np.abs(aec).max() < 1e-15


def test_the_gate_is_the_smallest_one_minus_sensor_of_the_cell():
    """``w_K = min_a (1 − s_a)``: a node with s = 1 switches its cells off, s = 0.25 scales."""
    rng = np.random.default_rng(4)
    cells, mc, dq = _two_cells(lambda x: rng.normal(size=(x.shape[0], 3)))
    full = np.zeros((2, 4, 3))
    add_correction(cells, mc, dq, np.zeros(6), full)
    gated = np.zeros((2, 4, 3))
    sensor = np.array([1.0, 0.0, 0.25, 0.0, 0.0, 0.0])  # node 0 in cell 0, node 2 in cell 1
    add_correction(cells, mc, dq, sensor, gated)
    assert np.abs(gated[0]).max() == 0.0
    assert np.allclose(gated[1], 0.75 * full[1], rtol=1e-14, atol=0)


def test_sensor_is_zero_on_linear_data_and_one_at_an_extremum():
    """Jameson's sensor sums over a 3 × 3 patch: 0 on a plane, 1 at a peak (δ = 0)."""
    xs = np.arange(3.0)
    x, y = np.meshgrid(xs, xs)
    nodes = np.arange(9).reshape(3, 3)
    cells = np.array([[nodes[j, i], nodes[j, i + 1], nodes[j + 1, i], nodes[j + 1, i + 1]]
                      for j in range(2) for i in range(2)])
    for h, expected in ((2.0 + 0.3 * x.ravel() - 0.1 * y.ravel(), 0.0),
                        (np.where(np.arange(9) == 4, 1.0, 0.0), 1.0)):
        buf = np.zeros((4, 4, 5))
        high = np.arange(48.0).reshape(4, 4, 3)
        sensor_sums(cells, h, high, buf)
        assert np.array_equal(buf[:, :, :3], high)
        s1 = np.zeros(9)
        s2 = np.zeros(9)
        np.add.at(s1, cells.ravel(), buf[:, :, 3].ravel())
        np.add.at(s2, cells.ravel(), buf[:, :, 4].ravel())
        assert abs(abs(s1[4]) / s2[4] - expected) < 1e-14


@pytest.mark.parametrize("correct", [True, False])
def test_hemisphere_volume_is_exact_with_and_without(correct):
    """The correction is conservative: the hemisphere keeps its volume to round-off."""
    case = load_case(CASES / "hemisphere.yaml",
                     ["domain.cells=[50,50]", f"numerics.mass_correction={str(correct).lower()}"])
    r = run(case, write=False, comm=COMM)
    w = nodal_weights(r.x, r.y)  # the lumped mass: the scheme's volume is Σ m_i h_i
    h0 = np.sqrt(np.maximum(25.0 - (r.x - 25.0) ** 2 - (r.y - 25.0) ** 2, 0.0))
    dried = r.summary["dried_volume"]  # the films thinner than the dry tolerance
    assert dried >= 0.0
    assert abs((np.sum(w * r.h) + dried) / np.sum(w * h0) - 1.0) < 1e-12


def test_correction_lowers_the_hemisphere_error():
    """Relative L1 against the radial reference at 100²: lower with the correction."""
    errors = {}
    for correct in (True, False):
        case = load_case(CASES / "hemisphere.yaml", [
            "domain.cells=[100,100]", f"numerics.mass_correction={str(correct).lower()}"])
        r = run(case, write=False, comm=COMM)
        errors[correct] = hemisphere_errors(r.x, r.y, r.h, nodal_weights(r.x, r.y),
                                            (25.0, 25.0), r.t, case.gravity)["l1"]
    assert errors[True] < 0.9 * errors[False]
