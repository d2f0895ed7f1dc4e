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


PENTAGON = {"name": "pent", "method": "tg2",
            "domain": {"outline": [[0, 0], [40, 0], [50, 30], [20, 45], [-5, 25]],
                       "cell_size": 2.5, "boundary": "wall"},
            "terrain": {"elevation": "0.05 * x"},
            "initial": {"depth": "maximum(2 - 0.05*((x-20)**2 + (y-20)**2), 0)"},
            "material": {"density": 1000, "friction": {"law": "voellmy", "mu": 0.2,
                                                        "xi": 500}},
            "time": {"end": 1.0, "cfl": 0.9}, "output": {"every": 1.0, "pictures": False}}


def test_a_gmsh_mesh_compares_on_its_own_nodes(tmp_path):
    """An outline case: maps from the runs' rasters, the difference on the mesh's nodes."""
    import yaml

    path = tmp_path / "pent.yaml"
    path.write_text(yaml.safe_dump(PENTAGON))
    proc = _compare(path, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "out" / "compare_fields.png").stat().st_size > 10_000
    line = next(x for x in (tmp_path / "out" / "compare.md").read_text().splitlines()
                if x.startswith("Depth difference"))
    l1 = float(line.split("L1 = ")[1].split(" ")[0])
    linf = float(line.split("L∞ = ")[1].split(" ")[0])
    volume = np.pi * 40.0  # the paraboloid's ½ π R² h0, R² = 40 m², h0 = 2 m
    assert 0.0 < l1 < 2.0 * volume and 0.0 < linf < 2.0  # within what both runs hold


def test_difference_weights_a_meshs_nodes_by_its_lumped_mass():
    from types import SimpleNamespace

    from fem_runout.compare import difference

    rng = np.random.default_rng(3)
    x, y, area = rng.random(50) * 40, rng.random(50) * 30, rng.random(50) + 0.5
    a = SimpleNamespace(x=x, y=y, area=area, h=rng.random(50))
    b = SimpleNamespace(x=x, y=y, area=area, h=rng.random(50))
    l1, linf = difference(a, b)
    assert l1 == pytest.approx(float(np.sum(area * np.abs(a.h - b.h))), rel=1e-14)
    assert linf == float(np.abs(a.h - b.h).max())
