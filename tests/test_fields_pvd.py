"""FieldWriter's VTK companion ``fields.pvd`` opens in pyvista with the values written."""

from __future__ import annotations

from mpi4py import MPI

# isort: split

import numpy as np
import pytest
import pyvista as pv

from fem_runout.callbacks import StepInfo
from fem_runout.output import FIELD_NAMES, FieldWriter, read_vtx_bp4
from tests.fake_solver import fake_solver

NX, NY, LX, LY = 8, 4, 4.0, 2.0
THRESHOLD = 1e-3
TIMES = [0.0, 0.5]


def make_solver(comm, h, hu, hv, z):
    """A stand-in for a Solver: Q1 fields interpolated from formulas of ``(x, y)``."""
    return fake_solver(comm, {"h": h, "hu": hu, "hv": hv, "z": z}, (NX, NY), (LX, LY))


def by_coordinates(points, values):
    """``values`` ordered by (y, x) of ``points`` (rounded: the file has 1e-17 noise)."""
    p = np.round(np.asarray(points)[:, :2], 9)
    return np.asarray(values)[np.lexsort((p[:, 0], p[:, 1]))]


def read_pvd(path):
    """Time values and, per time, the (single) grid of the PVD collection."""
    reader = pv.get_reader(str(path))
    times = list(reader.time_values)
    grids = []
    for t in times:
        reader.set_active_time_value(t)
        data = reader.read()
        grid = data.combine() if isinstance(data, pv.MultiBlock) else data
        grids.append(grid)
    return times, grids


@pytest.fixture
def written(tmp_path):
    """Run FieldWriter start/output/output/finish; return the solver and the expected h."""
    s = make_solver(
        MPI.COMM_SELF,
        lambda x, y: 1 + x / 4,
        lambda x, y: x,
        lambda x, y: y,
        lambda x, y: 0.1 * y,
    )
    writer = FieldWriter(tmp_path, s, threshold=THRESHOLD)
    coords = s.V.tabulate_dof_coordinates()
    expected = []
    info = StepInfo(t=TIMES[0], dt=0.0, step=0)
    writer.start(s, info)
    writer.output(s, info)
    expected.append(by_coordinates(coords, s.fields["h"].x.array.copy()))
    s.fields["h"].x.array[:] += 0.5
    info = StepInfo(t=TIMES[1], dt=0.5, step=1)
    writer.step(s, info)
    writer.output(s, info)
    expected.append(by_coordinates(coords, s.fields["h"].x.array.copy()))
    writer.finish(s, info)
    return tmp_path, writer, expected


def test_pvd_and_bp_exist(written):
    out, writer, _ = written
    assert writer.pvd_path == out / "fields.pvd"
    assert (out / "fields.pvd").is_file()
    assert (out / "fields.bp").is_dir()
    assert len(read_vtx_bp4(out / "fields.bp")) == len(TIMES)


def test_pvd_time_steps(written):
    out, _, _ = written
    times, grids = read_pvd(out / "fields.pvd")
    assert times == pytest.approx(TIMES)
    assert len(grids) == len(TIMES)


def test_pvd_depth_matches_written_values(written):
    out, _, expected = written
    _, grids = read_pvd(out / "fields.pvd")
    for grid, h_expected in zip(grids, expected, strict=True):
        assert grid.n_points == (NX + 1) * (NY + 1)
        assert set(FIELD_NAMES) <= set(grid.point_data.keys())
        h = by_coordinates(grid.points, grid.point_data["h"])
        np.testing.assert_allclose(h, h_expected, rtol=0, atol=1e-6)


def test_pvd_derived_fields(written):
    out, _, _ = written
    _, grids = read_pvd(out / "fields.pvd")
    for grid, extra in zip(grids, [0.0, 0.5], strict=True):
        x, y = grid.points[:, 0], grid.points[:, 1]
        h = 1 + x / 4 + extra
        np.testing.assert_allclose(grid.point_data["h"], h, atol=1e-6)
        np.testing.assert_allclose(grid.point_data["eta"], h + 0.1 * y, atol=1e-6)
        velocity = grid.point_data["velocity"]
        assert velocity.shape == (grid.n_points, 3)
        np.testing.assert_allclose(velocity[:, 0], x / h, atol=1e-6)
        np.testing.assert_allclose(velocity[:, 1], y / h, atol=1e-6)


def test_pvd_can_be_switched_off(tmp_path):
    s = make_solver(
        MPI.COMM_SELF,
        lambda x, y: 1 + 0 * x,
        lambda x, y: 0 * x,
        lambda x, y: 0 * x,
        lambda x, y: 0 * x,
    )
    writer = FieldWriter(tmp_path, s, pvd=False)
    info = StepInfo(t=0.0, dt=0.0, step=0)
    writer.start(s, info)
    writer.output(s, info)
    writer.finish(s, info)
    assert writer.pvd_path is None
    assert not (tmp_path / "fields.pvd").exists()
    assert (tmp_path / "fields.bp").is_dir()
