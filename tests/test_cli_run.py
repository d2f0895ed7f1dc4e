"""End to end: ``mpiexec -n 2 python -m fem_runout CASE`` writes every output, readable."""

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fem_runout.config import load_case
from fem_runout.output import SERIES_COLUMNS, read_vtx_bp4

ROOT = Path(__file__).resolve().parents[1]
MPIEXEC = Path(sys.executable).parent / "mpiexec"


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "run"
    cmd = [str(MPIEXEC), "-n", "2", sys.executable, "-m", "fem_runout",
           str(ROOT / "cases" / "inclined_dam_break.yaml"), "--out", str(out),
           "--set", "domain.cells=[120,8]", "--set", "time.end=2.0", "--set", "output.every=1.0",
           "--set", "output.vtk=true"]
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)
    return proc, out, cmd, env


def test_run_succeeds_and_writes_all_outputs(demo):
    proc, out, _, _ = demo
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "done:" in proc.stdout and "relative mass error" in proc.stdout
    for name in ("case.resolved.yaml", "fields.bp", "peaks.bp", "series.csv", "series.png",
                 "depth.png", "peak_depth.png", "fields.pvd"):
        assert (out / name).exists(), name
    for png in ("series.png", "depth.png", "peak_depth.png"):
        assert (out / png).stat().st_size > 10_000


def test_resolved_case_round_trips(demo):
    _, out, _, _ = demo
    case = load_case(out / "case.resolved.yaml")
    assert case.domain.resolved_cells == (120, 8)
    assert case.time.end == 2.0 and case.output.every == 1.0


def test_series_columns_and_mass(demo):
    _, out, _, _ = demo
    with open(out / "series.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0].keys()) == list(SERIES_COLUMNS)
    t = np.array([float(r["t"]) for r in rows])
    assert t[0] == 0.0 and abs(t[-1] - 2.0) < 1e-12
    # open boundaries: volume + outflow is conserved
    assert max(abs(float(r["mass_error"])) for r in rows) < 1e-12
    front = np.array([float(r["front_x"]) for r in rows])
    assert np.all(np.diff(front) >= 0) and front[-1] > 40.0


def test_fields_read_back_with_pyvista_and_bp_reader(demo):
    pv = pytest.importorskip("pyvista")
    _, out, _, _ = demo
    steps = read_vtx_bp4(out / "fields.bp")
    assert [round(float(np.ravel(s["step"])[0]), 9) for s in steps] == [0.0, 1.0, 2.0]
    reader = pv.get_reader(str(out / "fields.pvd"))
    assert len(reader.time_values) == 3
    reader.set_active_time_value(reader.time_values[-1])
    grid = reader.read().combine()
    owned = grid.point_data["vtkGhostType"] == 0
    pts = np.asarray(grid.points)[owned]
    h_pv = np.asarray(grid.point_data["h"])[owned]
    last = steps[-1]
    first = steps[0]  # the mesh (geometry, ghost marks) is written with the first step only
    keep = first.get("vtkGhostType", np.zeros(len(last["h"]))) == 0
    bp_pts, h_bp = first["geometry"][keep], last["h"][keep]
    o1 = np.lexsort((np.round(pts[:, 0], 9), np.round(pts[:, 1], 9)))
    o2 = np.lexsort((np.round(bp_pts[:, 0], 9), np.round(bp_pts[:, 1], 9)))
    assert len(o1) == len(o2) == 121 * 9
    np.testing.assert_allclose(h_pv[o1], h_bp[o2], atol=1e-6)
    assert h_bp.max() > 1.0


def test_rerun_without_overwrite_is_refused(demo):
    _, out, cmd, env = demo
    before = sorted(p.name for p in out.iterdir())
    proc = subprocess.run([c for c in cmd if c != "--overwrite"], capture_output=True, text=True,
                          timeout=120, env=env, cwd=ROOT)
    assert proc.returncode == 2
    assert "not empty" in proc.stderr and "--overwrite" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == before
