"""Outputs on a real 8 x 4 Q1 mesh of [0, 4] x [0, 2] with fields of known formulas."""

from __future__ import annotations

import csv

from mpi4py import MPI

# isort: split

import numpy as np
import pytest

from fem_runout.callbacks import StepInfo
from fem_runout.output import (
    FIELD_NAMES,
    SERIES_COLUMNS,
    FieldWriter,
    PeakTracker,
    Pictures,
    SeriesRecorder,
    compute_diagnostics,
    gather_nodal,
    grid_shape,
    read_vtx_bp4,
    render_depth,
)
from tests.fake_solver import fake_solver

NX, NY, LX, LY = 8, 4, 4.0, 2.0
RHO = 2000.0
THRESHOLD = 1e-3


def make_solver(comm, h, hu, hv, z):
    """A stand-in for a Solver: Q1 fields interpolated from formulas of ``(x, y)``."""
    return fake_solver(comm, {"h": h, "hu": hu, "hv": hv, "z": z}, (NX, NY), (LX, LY))


def trapezoid_weights():
    """Exact lumped Q1 masses of the uniform grid, in (y, x) sorted order, shape (NY+1, NX+1)."""
    wx = np.full(NX + 1, LX / NX)
    wx[[0, -1]] /= 2
    wy = np.full(NY + 1, LY / NY)
    wy[[0, -1]] /= 2
    return np.outer(wy, wx)


GRID_X, GRID_Y = np.meshgrid(np.linspace(0, LX, NX + 1), np.linspace(0, LY, NY + 1))


def linear_solver(comm=MPI.COMM_SELF):
    return make_solver(
        comm, lambda x, y: 1 + x / 4, lambda x, y: x, lambda x, y: y, lambda x, y: 0.1 * y
    )


def test_gather_nodal_sorted_by_y_then_x():
    s = linear_solver()
    arrays = {k: f.x.array for k, f in s.fields.items()}  # ghosts included: ignored
    g = gather_nodal(s.V, arrays)
    assert set(g) == {"x", "y", "h", "hu", "hv", "z"}
    assert g["x"].shape == ((NX + 1) * (NY + 1),)
    np.testing.assert_allclose(g["x"].reshape(NY + 1, NX + 1), GRID_X, atol=1e-14)
    np.testing.assert_allclose(g["y"].reshape(NY + 1, NX + 1), GRID_Y, atol=1e-14)
    np.testing.assert_allclose(g["h"], 1 + g["x"] / 4, atol=1e-14)
    np.testing.assert_allclose(g["z"], 0.1 * g["y"], atol=1e-14)
    assert grid_shape(g["x"], g["y"]) == (NX, NY)


def test_gathered_coordinates_are_the_meshs_own_numbers():
    """x = 50 on a 2.5 m grid is 50 exactly, not the last-bit push-forward of the tabulation."""
    from fem_runout.mesh import node_coordinates

    s = fake_solver(MPI.COMM_WORLD, {k: (lambda x, y: 0 * x) for k in ("h", "hu", "hv", "z")},
                    (40, 2), (100.0, 2.0))
    np.testing.assert_allclose(node_coordinates(s.V), s.V.tabulate_dof_coordinates(),
                               rtol=0, atol=1e-12)
    g = gather_nodal(s.V, {"h": s.fields["h"].x.array})
    if g is not None:
        assert np.array_equal(g["x"].reshape(3, 41), np.tile(np.arange(41) * 2.5, (3, 1)))
        assert np.count_nonzero(g["x"] > 50.0) == 3 * 20


def test_gather_nodal_rejects_short_arrays():
    s = linear_solver()
    with pytest.raises(ValueError, match="owned"):
        gather_nodal(s.V, {"h": np.zeros(3)})


def test_diagnostics_linear_fields():
    s = linear_solver()
    d = compute_diagnostics(s, THRESHOLD, RHO)
    w = trapezoid_weights()
    h = 1 + GRID_X / 4
    assert abs(d["volume"] - 12.0) < 1e-12  # lumped Q1 integrates bilinear fields exactly
    ke = np.sum(w * 0.5 * RHO * (GRID_X**2 + GRID_Y**2) / h)
    assert d["kinetic_energy"] == pytest.approx(ke, rel=1e-13)
    assert d["max_depth"] == pytest.approx(2.0, abs=1e-14)
    assert d["max_speed"] == pytest.approx(np.sqrt(4**2 + 2**2) / 2, rel=1e-14)
    assert d["wet_area"] == pytest.approx(LX * LY, rel=1e-14)
    assert d["front_x"] == pytest.approx(4.0, abs=1e-14)
    assert d["outflow"] == 0.0


def test_diagnostics_depth_step_and_dry_state():
    s = make_solver(
        MPI.COMM_SELF,
        lambda x, y: np.where(x < 2.2, 1.0, 0.0),
        lambda x, y: 0.5 * x,
        lambda x, y: 0.0 * x,
        lambda x, y: 0.0 * x,
    )
    d = compute_diagnostics(s, THRESHOLD, RHO)
    assert d["front_x"] == pytest.approx(2.0, abs=1e-14)
    assert d["wet_area"] == pytest.approx(2.25 * LY, rel=1e-14)  # columns x = 0 .. 2
    assert d["volume"] == pytest.approx(2.25 * LY, rel=1e-14)
    assert d["max_speed"] == pytest.approx(1.0, rel=1e-14)  # hu = x / 2 at x = 2, h = 1
    s.fields["h"].x.array[:] = 0.0
    d = compute_diagnostics(s, THRESHOLD, RHO)
    assert np.isnan(d["front_x"])
    assert d["max_speed"] == 0.0 and d["wet_area"] == 0.0 and d["kinetic_energy"] == 0.0


def _numpy_diagnostics(s, threshold, density):
    """The NumPy form compute_diagnostics had before its kernels (the reference)."""
    from fem_runout.callbacks import flow_index
    from fem_runout.exact_sum import exact_totals
    from fem_runout.output.diagnostics import owned_x

    idx = flow_index(s)
    x = owned_x(s)[idx]
    m = np.asarray(s.lumped_mass, dtype=np.float64)[idx]
    h, hu, hv = (s.fields[k].x.array[idx].real for k in ("h", "hu", "hv"))
    wet = h > threshold
    q2 = hu[wet] ** 2 + hv[wet] ** 2
    terms = (m * h, 0.5 * density * (m[wet] * q2 / h[wet]), m[wet])
    speed = np.sqrt(q2) / h[wet]
    top = np.array([*(np.abs(t).max(initial=0.0) for t in terms),
                    max(h.max(initial=0.0), 0.0) if s.V.dofmap.index_map.size_local else -np.inf,
                    speed.max() if speed.size else 0.0,
                    x[wet].max() if speed.size else -np.inf])
    s.comm.Allreduce(MPI.IN_PLACE, top, op=MPI.MAX)
    sums = exact_totals(terms, top[:3], s.V.dofmap.index_map.size_global, s.comm)
    return [*sums, *top[3:]]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_diagnostics_kernels_give_the_numpy_forms_bits(seed):
    rng = np.random.default_rng(seed)
    s = linear_solver()
    n = s.fields["h"].x.array.size
    for wet_share in (0.0, 0.3, 1.0):  # all dry, a front, all wet
        h = np.where(rng.random(n) < wet_share, rng.lognormal(-1.0, 2.0, n),
                     rng.random(n) * THRESHOLD)
        s.fields["h"].x.array[:] = h
        for k in ("hu", "hv"):
            s.fields[k].x.array[:] = h * rng.normal(0.0, 30.0, n)
        d = compute_diagnostics(s, THRESHOLD, RHO)
        got = [d[k] for k in ("volume", "kinetic_energy", "wet_area", "max_depth",
                              "max_speed", "front_x")]
        want = _numpy_diagnostics(s, THRESHOLD, RHO)
        want[-1] = want[-1] if np.isfinite(want[-1]) else np.nan
        assert np.array_equal(np.array(got), np.array(want), equal_nan=True), (wet_share, got,
                                                                               want)
    assert d["volume"] > 0 and d["kinetic_energy"] > 0


def run_callbacks(s, callbacks, states, output_every=1):
    """Drive callbacks like the runner: ``states`` are functions mutating the solver per step."""
    info = StepInfo(t=0.0, dt=0.0, step=0)
    for cb in callbacks:
        cb.start(s, info)
    for cb in callbacks:
        cb.output(s, info)
    for k, mutate in enumerate(states, start=1):
        mutate(s)
        info = StepInfo(t=0.25 * k, dt=0.25, step=k)
        for cb in callbacks:
            cb.step(s, info)
        if k % output_every == 0:
            for cb in callbacks:
                cb.output(s, info)
    for cb in callbacks:
        cb.finish(s, info)
    return info


def drain(s):
    """Move 0.1 m of depth out through the boundary: volume + outflow is conserved."""
    s.fields["h"].x.array[:] -= 0.1
    s.outflow_volume += 0.1 * LX * LY


def test_series_recorder_csv(tmp_path):
    s = make_solver(
        MPI.COMM_SELF,
        lambda x, y: 0.5 + 0.0 * x,
        lambda x, y: 0.2 + 0.0 * x,
        lambda x, y: 0.0 * x,
        lambda x, y: 0.0 * x,
    )
    rec = SeriesRecorder(tmp_path / "series.csv", THRESHOLD, RHO)
    run_callbacks(s, [rec], [drain, drain, drain])
    with (tmp_path / "series.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert tuple(rows[0]) == SERIES_COLUMNS
    assert len(rows) == 4
    series = rec.series
    np.testing.assert_allclose([float(r["t"]) for r in rows], [0, 0.25, 0.5, 0.75])
    np.testing.assert_allclose(series["volume"], [4.0, 3.2, 2.4, 1.6], rtol=1e-13)
    np.testing.assert_allclose(series["outflow"], [0.0, 0.8, 1.6, 2.4], rtol=1e-13)
    assert np.max(np.abs(series["mass_error"])) < 1e-14
    assert np.max(np.abs([float(r["mass_error"]) for r in rows])) < 1e-14
    np.testing.assert_allclose(series["max_speed"], 0.2 / np.array([0.5, 0.4, 0.3, 0.2]))


def test_peak_tracker_envelope_and_file(tmp_path):
    s = linear_solver()

    def flatten(s):
        s.fields["h"].x.array[:] = 1.5
        s.fields["hu"].x.array[:] = 6.0

    peaks = PeakTracker(tmp_path, THRESHOLD)
    run_callbacks(s, [peaks], [flatten])
    g = peaks.gathered()
    x, y = g["x"], g["y"]
    np.testing.assert_allclose(g["peak_depth"], np.maximum(1 + x / 4, 1.5), atol=1e-14)
    speed = np.maximum(np.hypot(x, y) / (1 + x / 4), np.hypot(6.0, y) / 1.5)
    np.testing.assert_allclose(g["peak_speed"], speed, rtol=1e-14)
    (step,) = read_vtx_bp4(tmp_path / "peaks.bp")
    px = step["geometry"][:, 0]
    np.testing.assert_allclose(step["peak_depth"], np.maximum(1 + px / 4, 1.5), atol=1e-12)


def test_field_writer_roundtrip(tmp_path):
    s = linear_solver()
    writer = FieldWriter(tmp_path, s, threshold=THRESHOLD)

    def rise(s):
        s.fields["h"].x.array[:] += 0.5

    run_callbacks(s, [writer], [rise, rise], output_every=2)
    steps = read_vtx_bp4(tmp_path / "fields.bp")
    assert len(steps) == 2
    assert [float(st["step"][0]) for st in steps] == [0.0, 0.5]
    geometry = steps[0]["geometry"]
    assert geometry.shape == ((NX + 1) * (NY + 1), 3)
    x, y = geometry[:, 0], geometry[:, 1]
    for st, extra in zip(steps, [0.0, 1.0], strict=True):
        assert set(FIELD_NAMES) <= set(st)
        h = 1 + x / 4 + extra
        assert np.max(np.abs(st["h"] - h)) < 1e-12
        assert np.max(np.abs(st["eta"] - (h + 0.1 * y))) < 1e-12
        np.testing.assert_allclose(st["velocity"][:, 0], x / h, atol=1e-12)
        np.testing.assert_allclose(st["velocity"][:, 1], y / h, atol=1e-12)
        assert np.all(st["velocity"][:, 2] == 0.0)
    # the file's point order is the function's dof order
    np.testing.assert_allclose(steps[1]["h"], s.fields["h"].x.array, atol=1e-15)


def test_velocity_is_zero_where_dry(tmp_path):
    s = linear_solver()
    s.fields["h"].x.array[:4] = 0.0
    writer = FieldWriter(tmp_path, s, threshold=THRESHOLD)
    writer.update(s)
    v = writer.velocity.x.array.reshape(-1, 2)
    assert np.all(v[:4] == 0.0) and np.all(np.isfinite(v))


def png_colours(path):
    from PIL import Image

    with Image.open(path) as img:
        return len(img.convert("RGB").getcolors(maxcolors=1 << 20))


def test_pictures(tmp_path):
    s = linear_solver()
    rec = SeriesRecorder(tmp_path / "series.csv", THRESHOLD, RHO)
    peaks = PeakTracker(None, THRESHOLD)
    pics = Pictures(tmp_path, "linear test", recorder=rec, peaks=peaks, threshold=THRESHOLD)
    run_callbacks(s, [rec, peaks, pics], [drain, drain])
    names = sorted(p.name for p in pics.written)
    assert names == ["depth.png", "peak_depth.png", "series.png"]
    for name in names:
        assert (tmp_path / name).stat().st_size > 10_000
        assert png_colours(tmp_path / name) > 50  # anti-aliased plot, colour map: not blank


def test_render_depth_grey_where_dry(tmp_path):
    g = GRID_X.ravel(), GRID_Y.ravel()
    h = np.where(g[0] < 2.0, 1.0, 0.0)
    out = render_depth(*g, 0.1 * g[1], h, NX, NY, tmp_path / "d.png", THRESHOLD)
    assert out is not None and out.stat().st_size > 10_000


def test_render_depth_leaves_out_what_lies_outside_a_mesh(tmp_path):
    """A mesh sampled on a raster has NaN bed outside its outline: those cells are not drawn."""
    import pyvista

    g = GRID_X.ravel(), GRID_Y.ravel()
    z = np.where(g[0] + g[1] <= 4.0, 0.1 * g[1], np.nan)  # a triangle of the rectangle
    h = np.where(g[0] < 2.0, 1.0, 0.0)
    out = render_depth(*g, z, h, NX, NY, tmp_path / "d.png", THRESHOLD)
    assert out is not None and out.stat().st_size > 10_000
    assert png_colours(out) > 50
    full = render_depth(*g, 0.1 * g[1], h, NX, NY, tmp_path / "f.png", THRESHOLD)
    img, whole = (np.asarray(pyvista.read(str(p)).active_scalars) for p in (out, full))
    assert img.shape == whole.shape
    assert not np.array_equal(img, whole)  # the cut-off part is background, not terrain
