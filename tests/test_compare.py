"""``python -m fem_runout compare CASE``: every implemented method side by side."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fem_runout.api import IMPLEMENTED_METHODS
from fem_runout.compare import ALL_METHODS

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
    for method in sorted(IMPLEMENTED_METHODS):
        assert (out / method / "series.csv").exists(), method
    for method in ALL_METHODS:
        assert method in text
    if len(IMPLEMENTED_METHODS) == 1:
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
