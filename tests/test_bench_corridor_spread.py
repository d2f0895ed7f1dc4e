"""The corridor-spread bench's draws and statistics (pure numbers, no runs)."""

import pytest

from fem_runout.bench.corridor_spread import STEP, cfl_offsets, compare_clouds


def test_offsets_alternate_around_the_case_and_are_distinct():
    off = cfl_offsets(5)
    assert off == pytest.approx([0.0, -STEP, STEP, -2 * STEP, 2 * STEP], abs=0.0)
    assert len(set(cfl_offsets(9))) == 9
    assert cfl_offsets(1) == [0.0]


def test_cloud_statistics():
    s = compare_clouds([100.0, 104.0], [102.0, 106.0])
    assert s["mean_ratio"] == pytest.approx(104.0 / 102.0 - 1.0, rel=1e-14)
    assert s["low"] == pytest.approx(102.0 / 104.0 - 1.0, rel=1e-14)
    assert s["high"] == pytest.approx(106.0 / 100.0 - 1.0, rel=1e-14)
    assert s["grid_spread"] == pytest.approx(2.0 / 102.0, rel=1e-14)
    assert s["corridor_spread"] == pytest.approx(2.0 / 104.0, rel=1e-14)
