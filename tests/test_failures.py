"""Failures end cleanly: NaN stops the run with the last good state saved; a crash on one rank
ends the whole MPI job quickly."""

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from fem_runout.callbacks import StepInfo
from fem_runout.errors import SimulationError
from fem_runout.runner import Runner, Schedule

ROOT = Path(__file__).resolve().parents[1]
MPIEXEC = Path(sys.executable).parent / "mpiexec"


class _FakeSolver:
    """A scalar 'solver' whose state turns NaN at a given step."""

    def __init__(self, bad_step):
        self.state, self.bad_step, self.calls = 1.0, bad_step, 0

    def stable_dt(self):
        return 0.1

    def advance(self, dt):
        self.calls += 1
        self.state = np.nan if self.calls == self.bad_step else self.state + dt

    def snapshot(self):
        return self.state

    def restore(self, snap):
        self.state = snap

    def health(self, also_max=None):
        return None if np.isfinite(self.state) else "the state has NaN"


class _Log:
    def __init__(self):
        self.events = []

    def start(self, s, i):
        self.events.append(("start", i.t))

    def step(self, s, i):
        pass

    def output(self, s, i):
        self.events.append(("output", round(i.t, 12), s.state))

    def finish(self, s, i):
        self.events.append(("finish", round(i.t, 12)))


def test_nan_stops_the_run_and_writes_the_last_good_state():
    solver, log = _FakeSolver(bad_step=4), _Log()
    with pytest.raises(SimulationError, match="last good state"):
        Runner(solver, Schedule(end=10.0, cfl=1.0, every=5.0), [log]).run()
    assert solver.state == pytest.approx(1.3)  # restored after step 3
    assert log.events[-2] == ("output", 0.3, pytest.approx(1.3))
    assert log.events[-1] == ("finish", 0.3)


def test_runner_lands_on_output_times():
    solver, log = _FakeSolver(bad_step=-1), _Log()
    info = Runner(solver, Schedule(end=1.0, cfl=0.37, every=0.25), [log]).run()
    times = [e[1] for e in log.events if e[0] == "output"]
    assert times == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert info.t == pytest.approx(1.0, abs=1e-12)
    assert isinstance(info, StepInfo)


def _script(tmp_path, body):
    path = tmp_path / "job.py"
    path.write_text(textwrap.dedent(body))
    return path


def _run_mpi(script, tmp_path, timeout=120):
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    proc = subprocess.run([str(MPIEXEC), "-n", "2", sys.executable, str(script)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=timeout, env=env)
    return proc, time.perf_counter() - t0


CASE = str(ROOT / "cases" / "hemisphere.yaml")


def test_exception_on_one_rank_ends_the_whole_job(tmp_path):
    script = _script(tmp_path, f"""
        from mpi4py import MPI
        import fem_runout.tg2.solver as s
        orig = s.TG2Solver.advance
        def advance(self, dt):
            self._n = getattr(self, "_n", 0) + 1
            if MPI.COMM_WORLD.rank == 1 and self._n == 3:
                import time
                open("failed_at", "w").write(repr(time.time()))
                raise RuntimeError("injected failure on rank 1")
            orig(self, dt)
        s.TG2Solver.advance = advance
        from fem_runout.cli import main
        raise SystemExit(main(["{CASE}", "--out", "out", "--quiet",
                               "--set", "domain.cells=[20,20]"]))
    """)
    proc, seconds = _run_mpi(script, tmp_path)
    ended = time.time()
    failed = float((tmp_path / "failed_at").read_text())
    print(proc.stderr[-2000:], f"ended {ended - failed:.1f} s after the failure")
    assert proc.returncode != 0
    assert proc.stderr.count("RuntimeError: injected failure on rank 1") == 1
    assert "[rank 1]" in proc.stderr
    assert ended - failed <= 10.0  # the bound: the whole job ends within 10 s


def test_nan_under_mpi_exits_3_with_last_state_written(tmp_path):
    script = _script(tmp_path, f"""
        import numpy as np
        import fem_runout.tg2.solver as s
        orig = s.TG2Solver.advance
        def advance(self, dt):
            orig(self, dt)
            self._n = getattr(self, "_n", 0) + 1
            if self._n == 5:
                self.transport.h.x.array[0] = np.nan
        s.TG2Solver.advance = advance
        from fem_runout.cli import main
        raise SystemExit(main(["{CASE}", "--out", "out", "--quiet",
                               "--set", "domain.cells=[20,20]"]))
    """)
    proc, _ = _run_mpi(script, tmp_path)
    print(proc.stderr[-2000:])
    assert proc.returncode == 3
    assert proc.stderr.count("error: stopped at t =") == 1
    assert "step 5" in proc.stderr and "last good state" in proc.stderr
    out = tmp_path / "out"
    assert (out / "fields.bp").is_dir() and (out / "series.csv").is_file()
    rows = (out / "series.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 5  # header, t=0 and the 4 good steps
