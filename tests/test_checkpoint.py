"""Checkpoints and restart: a restarted run equals an uninterrupted one, bit for bit."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.checkpoint import domain_differences, read_tree, write_tree
from fem_runout.config import load_case
from tests.cli_helpers import main_in

ROOT = Path(__file__).resolve().parents[1]
COMM = MPI.COMM_SELF
#: (case, overrides): small runs of each kind the issue names.
RUNS = {
    "hemisphere": ("cases/hemisphere.yaml", ["domain.cells=[30,30]", "time.end=0.9",
                                             "output.every=0.3"]),
    "bingham": ("cases/hemisphere_bingham.yaml", ["domain.cells=[30,30]", "time.end=0.6",
                                                   "output.every=0.3"]),
    "auto": ("cases/hard/pit.yaml", ["time.end=auto", "time.max=40", "output.every=3"]),
    "msh": ("cases/curved_channel.yaml", ["time.end=0.9", "output.every=0.3"]),  # gmsh mesh
}
FINAL = ("h", "hu", "hv", "peak_depth", "peak_speed")
SUMMARY = ("released_volume", "deposit_volume", "outflow_volume", "dried_volume",
           "affected_area", "peak_depth_max", "peak_speed_max", "peak_pressure_max",
           "runout_length", "t_end", "steps", "at_rest")


def case_of(name: str, method: str, out: Path, *extra: str):
    path, overrides = RUNS[name]
    return load_case(ROOT / path, [f"method={method}", f"output.dir={out}",
                                   "output.pictures=false", *overrides, *extra])


def assert_same_run(a, b, out_a: Path, out_b: Path) -> None:
    """Final fields, peaks, series, summary and series.csv identical."""
    for key in FINAL:
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert a.series.keys() == b.series.keys()
    for key in a.series:
        assert np.array_equal(a.series[key], b.series[key]), key
    for key in SUMMARY:
        assert a.summary[key] == b.summary[key], key
    assert (out_a / "series.csv").read_text() == (out_b / "series.csv").read_text()


def test_tree_round_trip(tmp_path):
    import h5py

    tree = {"a": 1.5, "b": "text\nmore", "c": None, "d": {"e": np.arange(5.0), "f": 3},
            "g": np.array([], dtype=np.float64)}
    with h5py.File(tmp_path / "t.h5", "w") as f:
        write_tree(f, tree)
    with h5py.File(tmp_path / "t.h5", "r") as f:
        back = read_tree(f)
    assert back["a"] == 1.5 and back["b"] == "text\nmore" and back["c"] is None
    assert np.array_equal(back["d"]["e"], np.arange(5.0)) and back["d"]["f"] == 3
    assert back["g"].size == 0


@pytest.mark.parametrize("method", ["tg2", "mpm"])
@pytest.mark.parametrize("name", list(RUNS))
def test_restart_equals_uninterrupted_run(tmp_path, method, name):
    whole = run(case_of(name, method, tmp_path / "whole"), comm=COMM)
    every = "3" if name == "auto" else "0.3"
    first = run(case_of(name, method, tmp_path / "cut", f"output.checkpoint.every={every}",
                      "output.checkpoint.keep=20"), comm=COMM)
    checkpoints = sorted((tmp_path / "cut" / "checkpoints").glob("checkpoint_*.h5"))
    assert len(checkpoints) >= 2
    # the second-to-last: mid-run (for end: auto, after the flow began to settle)
    resumed = run(case_of(name, method, tmp_path / "cut"), comm=COMM, restart=checkpoints[-2])
    assert resumed.steps == whole.steps == first.steps
    assert_same_run(whole, resumed, tmp_path / "whole", tmp_path / "cut")
    if name == "auto":
        assert whole.at_rest and resumed.at_rest and whole.t < 40.0


def _cli(*args: str, cwd: Path, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fem_runout", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


SLOW = ["--set", "domain.cells=[120,120]", "--set", "time.end=1.2", "--set",
        "output.checkpoint.every=0.15", "--set", "output.pictures=false", "--quiet"]


def _wait_for(pattern: str, folder: Path, count: int = 1, timeout: float = 120.0) -> None:
    deadline = time.time() + timeout
    while len(list(folder.glob(pattern))) < count:
        assert time.time() < deadline, f"no {pattern} in {folder}"
        time.sleep(0.02)


def _series(path: Path) -> list[list[str]]:
    with path.open() as f:
        return list(csv.reader(f))


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    """The uninterrupted :data:`SLOW` hemisphere run from the command line (its folder)."""
    folder = tmp_path_factory.mktemp("uninterrupted")
    proc = _cli(str(ROOT / "cases/hemisphere.yaml"), "--out", "whole", *SLOW, cwd=folder)
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    return folder / "whole"


def test_sigterm_writes_a_checkpoint_and_the_restart_finishes_the_same(tmp_path, whole, capsys,
                                                                       monkeypatch):
    case = str(ROOT / "cases/hemisphere.yaml")
    proc = _cli(case, "--out", "cut", *SLOW, cwd=tmp_path)
    _wait_for("cut/checkpoints/checkpoint_*.h5", tmp_path)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 143
    err = proc.stderr.read()
    assert err.startswith("stopped by SIGTERM at t = ") and "Traceback" not in err
    checkpoint = err.split("--restart ")[1].split()[0]
    assert Path(tmp_path / checkpoint).is_file()
    summary = json.loads((tmp_path / "cut" / "summary.json").read_text())
    assert summary["t_end"] < 1.2  # the outputs of the interrupted run were written
    again = main_in(tmp_path, [case, "--out", "cut", *SLOW, "--restart", checkpoint], capsys,
                    monkeypatch)  # the restart in this process: the same code
    assert again.returncode == 0, again.stderr
    a, b = (json.loads((d / "summary.json").read_text()) for d in (whole, tmp_path / "cut"))
    assert all(a[k] == b[k] for k in SUMMARY)
    assert _series(whole / "series.csv") == _series(tmp_path / "cut" / "series.csv")


def test_sigterm_under_mpiexec_stops_every_rank_and_restarts_on_one(tmp_path, whole, capsys,
                                                                    monkeypatch):
    case = str(ROOT / "cases/hemisphere.yaml")
    mpiexec = Path(sys.executable).parent / "mpiexec"
    proc = subprocess.Popen([str(mpiexec), "-n", "2", sys.executable, "-m", "fem_runout", case,
                             "--out", "cut", *SLOW], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    _wait_for("cut/checkpoints/checkpoint_*.h5", tmp_path)
    proc.send_signal(signal.SIGTERM)  # to mpiexec, which forwards it to both ranks
    assert proc.wait(timeout=60) == 143
    err = proc.stderr.read()
    assert err.count("stopped by SIGTERM at t = ") == 1 and "Traceback" not in err
    checkpoint = err.split("--restart ")[1].split()[0]
    again = main_in(tmp_path, [case, "--out", "cut", *SLOW, "--restart", checkpoint], capsys,
                    monkeypatch)  # the restart in this process: the same code
    assert again.returncode == 0, again.stderr
    a, b = (json.loads((d / "summary.json").read_text()) for d in (whole, tmp_path / "cut"))
    assert all(a[k] == b[k] for k in SUMMARY)


def test_sigkill_while_writing_a_checkpoint_keeps_the_previous_one(tmp_path, whole, capsys,
                                                                   monkeypatch):
    case = str(ROOT / "cases/hemisphere.yaml")
    # every checkpoint pauses 2 s between its temporary file and the rename (a test hook)
    env = {**__import__("os").environ, "FEM_RUNOUT_CHECKPOINT_PAUSE": "2"}
    proc = _cli(case, "--out", "cut", *SLOW, cwd=tmp_path, env=env)
    folder = tmp_path / "cut" / "checkpoints"
    _wait_for("checkpoint_*.h5", folder)  # the first is complete ...
    _wait_for("checkpoint_*.h5.tmp", folder)  # ... the second is being written: kill now
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    complete = sorted(folder.glob("checkpoint_*.h5"))
    assert len(complete) == 1 and list(folder.glob("*.tmp"))
    again = main_in(tmp_path, [case, "--out", "cut", *SLOW, "--restart", str(complete[0])],
                    capsys, monkeypatch)
    assert again.returncode == 0, again.stderr
    a, b = (json.loads((d / "summary.json").read_text()) for d in (whole, tmp_path / "cut"))
    assert all(a[k] == b[k] for k in SUMMARY)


@pytest.mark.parametrize(("extra", "message"), [
    (["--restart", "missing.h5"], "error: --restart: no checkpoint file 'missing.h5'"),
    (["--restart", "case.yaml"], "error: --restart: cannot read checkpoint 'case.yaml'"),
])
def test_bad_restart_is_a_clear_error(tmp_path, extra, message, capsys, monkeypatch):
    (tmp_path / "case.yaml").write_text("h5 it is not\n")
    proc = main_in(tmp_path, [str(ROOT / "cases/hemisphere.yaml"), "--out", "out", *extra],
                   capsys, monkeypatch)
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_restart_of_another_method_or_mesh_is_refused(tmp_path, capsys, monkeypatch):
    case = ROOT / "cases/hemisphere.yaml"
    run(case_of("hemisphere", "tg2", tmp_path / "a", "output.checkpoint.every=0.3"), comm=COMM)
    checkpoint = sorted((tmp_path / "a" / "checkpoints").glob("*.h5"))[0]
    mesh = "not this case's mesh"
    for extra, messages in (
            (["--method", "mpm"], ["is of method 'tg2', the case runs 'mpm'"]),
            (["--set", "domain.cells=[20,30]"], [mesh, "domain.cells: [30, 30] in the "
                                                 "checkpoint, [20, 30] here"]),
            # every node of this mesh is one of the checkpoint's: still another mesh
            (["--set", "domain.cells=[30,15]", "--set", "domain.extent=[0,50,0,25]"],
             [mesh, "domain.cells: [30, 30] in the checkpoint, [30, 15] here",
              "domain.extent: "])):
        proc = main_in(tmp_path, [str(case), "--out", "a", "--restart", str(checkpoint),
                                  *extra], capsys, monkeypatch)
        assert proc.returncode == 2
        err = proc.stderr
        assert all(m in err for m in messages) and "Traceback" not in err, err


def test_bad_state_saves_a_checkpoint_that_restarts_with_changed_numerics(tmp_path, capsys,
                                                                         monkeypatch):
    """The command line in this process (its exit codes and messages are the process's)."""
    case = str(ROOT / "cases/hemisphere.yaml")
    args = ["--set", "domain.cells=[30,30]", "--set", "time.end=0.9", "--set",
            "output.pictures=false", "--quiet"]
    whole = main_in(tmp_path, [case, "--out", "whole", *args], capsys, monkeypatch)
    assert whole.returncode == 0
    # the hemisphere collapses at up to 8 m/s: a 5 m/s limit stops it
    bad = main_in(tmp_path, [case, "--out", "cut", *args, "--set", "numerics.max_speed=5"],
                  capsys, monkeypatch)
    assert bad.returncode == 3
    err = bad.stderr
    assert "Traceback" not in err and err.count("\n") == 1
    assert "stopped at t = " in err and "above numerics.max_speed = 5 m/s near (x, y) = (" in err
    checkpoint = err.split("--restart ")[1].split(")")[0]
    again = main_in(tmp_path, [case, "--out", "cut", *args, "--restart", checkpoint], capsys,
                    monkeypatch)
    assert again.returncode == 0, again.stderr
    a, b = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("whole", "cut"))
    assert all(a[k] == b[k] for k in SUMMARY)


DISK_FULL = """
import resource, signal, sys
from mpi4py import MPI  # MPI needs its shared-memory files before the limit
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, 1_000_000))
from fem_runout.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_disk_full_is_one_message_and_earlier_outputs_stay_readable(tmp_path):
    import pyvista

    from fem_runout.output import read_vtx_bp4

    proc = subprocess.run(
        [sys.executable, "-c", DISK_FULL, str(ROOT / "cases/hemisphere.yaml"), "--out", "out",
         "--set", "domain.cells=[60,60]", "--set", "output.vtk=true", "--quiet"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 4, proc.stderr
    assert proc.stderr.startswith("error: cannot write the fields at t = ")
    assert "File too large" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1
    out = tmp_path / "out"
    rows = _series(out / "series.csv")
    assert rows[0][0] == "t" and len(rows) > 2 and all(len(r) == len(rows[0]) for r in rows)
    reader = pyvista.get_reader(str(out / "fields.pvd"))
    assert len(reader.time_values) >= 1
    reader.set_active_time_value(reader.time_values[-1])
    assert reader.read()[0].n_points == 61 * 61
    steps = read_vtx_bp4(out / "fields.bp")
    assert len(steps) >= len(reader.time_values)


def test_domain_differences_name_the_keys_an_old_checkpoint_lacks():
    old = "name: x\ndomain: {outline: o.geojson, cell_size: 5.0, boundary: open}\n"
    new = ("name: x\ndomain: {outline: o.geojson, cell_size: 5.0, boundary: open, "
           "smoothing: 20}\n")
    assert domain_differences(old, new) == ["domain.smoothing: absent in the checkpoint, 20 here"]
    assert domain_differences(new, new) == []
    assert domain_differences(new, old) == ["domain.smoothing: 20 in the checkpoint, absent here"]
    first = domain_differences("", new)[0]
    assert first == "domain.outline: absent in the checkpoint, o.geojson here"
