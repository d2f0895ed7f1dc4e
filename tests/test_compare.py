"""``python -m fem_runout compare CASE``: every implemented method side by side."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fem_runout.compare import ALL_METHODS
from fem_runout.methods import method_names

ROOT = Path(__file__).resolve().parents[1]
SMALL = ["--set", "domain.cells=[60,4]", "--set", "time.end=1.0", "--set", "output.every=0.5",
         "--set", "output.pictures=false"]


def _compare(*args):
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "fem_runout", "compare", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp") / "ritter"
    proc = _compare(ROOT / "cases" / "ritter.yaml", "--out", out, *SMALL)
    return proc, out


def test_compare_writes_report_and_figures(compared):
    proc, out = compared
    assert proc.returncode == 0, proc.stderr[-3000:]
    text = (out / "compare.md").read_text()
    for name in ("compare_fields.png", "compare_series.png"):
        assert (out / name).stat().st_size > 10_000, name
    for method in sorted(method_names()):
        assert (out / method / "series.csv").exists(), method
    for method in ALL_METHODS:
        assert method in text
    if len(method_names()) == 1:
        assert "not implemented" in text and "no depth difference" in text
    else:
        assert "Depth difference" in text


def test_compare_volume_row_is_conserved(compared):
    """Open boundaries: the report's volume-error row holds round-off values only."""
    _, out = compared
    row = next(line for line in (out / "compare.md").read_text().splitlines()
               if line.startswith("| max relative volume error"))
    values = [float(v) for v in row.split("|")[2:-1] if v.strip() != "not implemented"]
    assert values and np.max(values) < 1e-12


def test_compare_refuses_non_empty_output_without_overwrite(compared):
    _, out = compared
    proc = _compare(ROOT / "cases" / "ritter.yaml", "--out", out, *SMALL)
    assert proc.returncode == 2
    assert "not empty" in proc.stderr


@pytest.mark.parametrize("args", [["missing.yaml"], ["cases/ritter.yaml", "--set", "time.end=-1"],
                                  ["cases/ritter.yaml", "--bogus"]])
def test_compare_bad_input_exits_2(args, tmp_path):
    proc = _compare(*args, "--out", tmp_path / "x")
    assert proc.returncode == 2, proc.stderr
    assert not (tmp_path / "x").exists()


def test_two_method_report_and_difference(tmp_path):
    """The two-method path (used once mpm lands), on a run and a perturbed copy of it."""
    from dataclasses import replace

    from mpi4py import MPI

    from fem_runout.api import run
    from fem_runout.compare import plot_fields, plot_series, report
    from fem_runout.config import load_case

    case = load_case(ROOT / "cases" / "ritter.yaml", ["domain.cells=[40,2]", "time.end=0.5"])
    a = run(case, write=False, comm=MPI.COMM_SELF)
    b = replace(a, h=a.h + 0.01 * (a.x > 50), particles=1234)
    results = {"tg2": a, "mpm": b}
    text = report("ritter.yaml", tmp_path, results, 1)
    assert "not implemented" not in text and "| particles | – | 1234 |" in text
    # |Δh| = 0.01 on the 20 node columns x = 52.5 … 100 m (dx = 2.5 m): area 48.75 m × 2 m
    line = next(x for x in text.splitlines() if x.startswith("Depth difference"))
    assert "L∞ = 0.01 m" in line and "L1 = 0.975 m³" in line, line
    plot_fields(results, tmp_path / "f.png", "t")
    plot_series(results, tmp_path / "s.png", "t")
    assert (tmp_path / "f.png").stat().st_size > 10_000
