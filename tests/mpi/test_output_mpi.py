"""Outputs on COMM_WORLD (run under ``mpiexec -n 2``) agree with a serial computation."""

from __future__ import annotations

import csv
from pathlib import Path

from mpi4py import MPI

# isort: split

import numpy as np
import pytest

from fem_runout.callbacks import StepInfo
from fem_runout.output import (
    FieldWriter,
    PeakTracker,
    SeriesRecorder,
    compute_diagnostics,
    gather_nodal,
    read_vtx_bp4,
)
from tests.fake_solver import fake_solver

WORLD = MPI.COMM_WORLD
NX, NY = 8, 4


def formulas():
    return {
        "h": lambda x, y: np.where(x < 2.6, 1 + x / 4, 0.0),
        "hu": lambda x, y: x * y,
        "hv": lambda x, y: -y,
        "z": lambda x, y: 0.1 * y,
    }


def make_solver(comm):
    return fake_solver(comm, formulas(), (NX, NY), (4.0, 2.0))


def shared_tmp(tmp_path: Path) -> Path:
    """Rank 0's tmp_path, the same on every rank."""
    return Path(WORLD.bcast(str(tmp_path), root=0))


def serial_gather(arrays_of):
    """What gather_nodal gives on one rank (computed on rank 0 only)."""
    if WORLD.rank != 0:
        return None
    s = make_solver(MPI.COMM_SELF)
    return gather_nodal(s.V, arrays_of(s))


def test_gather_matches_serial():
    s = make_solver(WORLD)
    n_owned = s.V.dofmap.index_map.size_local
    assert WORLD.size == 1 or 0 < n_owned < (NX + 1) * (NY + 1)  # really distributed

    def arrays_of(s):
        return {k: f.x.array for k, f in s.fields.items()} | {"m": s.lumped_mass}

    g = gather_nodal(s.V, arrays_of(s))
    expected = serial_gather(arrays_of)
    if WORLD.rank != 0:
        assert g is None
        return
    assert set(g) == set(expected)
    for name in expected:
        np.testing.assert_allclose(g[name], expected[name], rtol=0, atol=1e-14, err_msg=name)
    assert g["x"].size == (NX + 1) * (NY + 1)
    np.testing.assert_allclose(np.sum(g["m"]), 8.0, rtol=1e-14)  # owned masses: no double count


def test_diagnostics_match_serial():
    d = compute_diagnostics(make_solver(WORLD), 1e-3, 2000.0)
    expected = compute_diagnostics(make_solver(MPI.COMM_SELF), 1e-3, 2000.0)
    for name, value in expected.items():
        assert d[name] == pytest.approx(value, rel=1e-12, abs=1e-14), name
    assert d["front_x"] == pytest.approx(2.5, abs=1e-14)
    assert WORLD.allgather(d["volume"]) == [d["volume"]] * WORLD.size


def test_series_peaks_and_fields_in_parallel(tmp_path):
    out = shared_tmp(tmp_path)
    s = make_solver(WORLD)
    rec = SeriesRecorder(out / "series.csv", 1e-3, 2000.0)
    peaks = PeakTracker(out, 1e-3)
    fields = FieldWriter(out, s, threshold=1e-3)
    callbacks = [rec, peaks, fields]
    info = StepInfo(0.0, 0.0, 0)
    for cb in callbacks:
        cb.start(s, info)
        cb.output(s, info)
    s.fields["h"].x.array[:] *= 0.5
    s.outflow_volume = rec.initial_volume * 0.5
    info = StepInfo(0.1, 0.1, 1)
    for cb in callbacks:
        cb.step(s, info)
        cb.output(s, info)
    for cb in callbacks:
        cb.finish(s, info)
    np.testing.assert_allclose(rec.series["mass_error"], [0.0, 0.0], atol=1e-14)
    g = peaks.gathered()
    WORLD.barrier()
    if WORLD.rank != 0:
        assert g is None
        return
    x = g["x"]
    np.testing.assert_allclose(g["peak_depth"], np.where(x < 2.6, 1 + x / 4, 0.0), atol=1e-14)
    with (out / "series.csv").open() as stream:
        assert len(list(csv.DictReader(stream))) == 2
    steps = read_vtx_bp4(out / "fields.bp")
    assert [float(st["step"][0]) for st in steps] == [0.0, 0.1]
    geometry = steps[0]["geometry"]
    owned = steps[0]["vtkGhostType"].ravel() == 0
    assert np.count_nonzero(owned) == (NX + 1) * (NY + 1)  # every node once, ghosts flagged
    px, py = geometry[:, 0], geometry[:, 1]
    for st, factor in zip(steps, [1.0, 0.5], strict=True):
        h = factor * np.where(px < 2.6, 1 + px / 4, 0.0)
        assert np.max(np.abs(st["h"] - h)) < 1e-12
        assert np.max(np.abs(st["eta"] - (h + 0.1 * py))) < 1e-12
        wet = h > 1e-3
        np.testing.assert_allclose(st["velocity"][wet, 0], (px * py)[wet] / h[wet], atol=1e-12)
        assert np.all(st["velocity"][~wet] == 0.0)
    (peak,) = read_vtx_bp4(out / "peaks.bp")
    pk = np.where(peak["geometry"][:, 0] < 2.6, 1 + peak["geometry"][:, 0] / 4, 0.0)
    assert np.max(np.abs(peak["peak_depth"] - pk)) < 1e-12


from fem_runout.runner import Runner, Schedule  # noqa: E402
from tests.test_step_reduction import (  # noqa: E402  (the same checks on every rank count)
    SCHEDULES,
    THRESHOLD,
    SlidingBump,
    test_a_recorded_step_sends_no_message_of_its_own,  # noqa: F401
    test_the_rows_are_those_of_compute_diagnostics,  # noqa: F401
)


def test_the_series_reduced_with_the_step_is_the_serial_series():
    series = []
    for comm in (WORLD, MPI.COMM_SELF):
        recorder = SeriesRecorder(None, THRESHOLD, 200.0)
        Runner(SlidingBump(comm), Schedule(2.0, 1.0, 10.0, **SCHEDULES["rest energy"]),
               [recorder]).run()
        series.append(recorder.series)
    for name, values in series[0].items():
        assert np.array_equal(values, series[1][name], equal_nan=True), name
