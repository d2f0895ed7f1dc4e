"""The method contract (issue 15): registry, Solver protocol, no method names outside it."""

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout.api import build_solver
from fem_runout.methods import METHODS, get, method_names
from fem_runout.solver_api import ParticleSolver, Solver
from tests.counting_comm import CountingComm
from tests.tg2_helpers import case

ROOT = Path(__file__).resolve().parents[1]
COMM = MPI.COMM_SELF
#: A small case that builds every operator: friction, rheology, slope and open sides.
SMALL = ("domain.cells=[12,12]", "material.friction.law=voellmy", "material.friction.mu=0.2",
         "material.friction.xi=500", "material.rheology.law=bingham",
         "material.rheology.viscosity=2e4", "material.rheology.yield_stress=20")


def _solver(method):
    return build_solver(case("hemisphere", f"method={method}", *SMALL), COMM)


def _fields(solver) -> dict[str, np.ndarray]:
    return {k: f.x.array.copy() for k, f in solver.fields.items()}


def test_the_registry_names_every_method_once():
    assert method_names() == tuple(METHODS)
    assert len(set(m.display for m in METHODS.values())) == len(METHODS)
    with pytest.raises(KeyError, match="available"):
        get("sph")


@pytest.mark.parametrize("method", method_names())
def test_a_solver_follows_the_protocol(method):
    solver = _solver(method)
    assert isinstance(solver, Solver)
    assert isinstance(solver, ParticleSolver) == get(method).particles
    for name, member in inspect.getmembers(Solver, inspect.isfunction):
        if name.startswith("_"):
            continue
        want = list(inspect.signature(member).parameters)[1:]
        got = list(inspect.signature(getattr(solver, name)).parameters)
        assert got == want, f"{type(solver).__name__}.{name}{got} != protocol {want}"
    assert solver.n_particles is None or solver.n_particles > 0


@pytest.mark.parametrize("method", method_names())
def test_the_next_step_size_rides_with_the_health_check(method):
    """After a step, ``health`` reduces the next ``stable_dt`` together with its flag and the
    caller's values: ``stable_dt`` then sends nothing and has the bits it computes alone."""
    solver, twin = _solver(method), _solver(method)
    dt = 0.5 * solver.stable_dt()
    solver.advance(dt)
    twin.advance(dt)
    extra = np.array([3.0, -1.0])
    assert solver.health(extra) is None and extra.tolist() == [3.0, -1.0]
    counting = CountingComm(COMM)
    solver.comm = counting
    if hasattr(solver, "disc"):
        solver.disc.comm = counting
    assert solver.stable_dt() == twin.stable_dt() and counting.total == 0


@pytest.mark.parametrize("method", method_names())
def test_queries_change_no_state(method):
    """stable_dt, health, snapshot and n_particles leave the state and the next step alone.

    ``quiet`` is never asked anything before its step, ``busy`` is asked every query three
    times: both take the same step to the bit (a solver may memoise what a query computed,
    but the query must not change what ``advance`` does).
    """
    quiet, busy = _solver(method), _solver(method)
    dt = 0.9 * _solver(method).stable_dt()
    before = _fields(busy)
    for _ in range(3):
        assert busy.stable_dt() > dt
        assert busy.health() is None
        busy.snapshot()
        _ = busy.n_particles
    after = _fields(busy)
    assert all(np.array_equal(before[k], after[k]) for k in before)
    quiet.advance(dt)
    busy.advance(dt)
    for key in ("h", "hu", "hv"):
        assert np.array_equal(quiet.fields[key].x.array, busy.fields[key].x.array), key


@pytest.mark.parametrize("method", method_names())
def test_restore_returns_to_the_snapshot(method):
    solver = _solver(method)
    snap = solver.snapshot()
    start = _fields(solver)
    dt = 0.9 * solver.stable_dt()
    solver.advance(dt)
    after = _fields(solver)
    solver.restore(snap)
    assert all(np.array_equal(start[k], f.x.array) for k, f in solver.fields.items())
    solver.advance(dt)
    assert all(np.array_equal(after[k], f.x.array) for k, f in solver.fields.items())


def _modules(package: str):
    for path in sorted((ROOT / package).rglob("*.py")):
        yield path, ast.parse(path.read_text(), filename=str(path))


def test_the_particle_method_imports_nothing_from_tg2():
    bad = []
    for path, tree in _modules("mpm"):
        for node in ast.walk(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            bad += [f"{path.name}: {n}" for n in names if n.startswith("fem_runout.tg2")]
    assert bad == []


def test_method_names_appear_only_in_the_registry():
    """No string literal equal to a method name in the code outside fem_runout/methods.py."""
    names = {*method_names(), "dampm"}
    found = []
    for package in ("fem_runout", "mpm"):
        for path, tree in _modules(package):
            if path == ROOT / "fem_runout" / "methods.py":
                continue
            found += [f"{path.relative_to(ROOT)}:{node.lineno}: {node.value!r}"
                      for node in ast.walk(tree)
                      if isinstance(node, ast.Constant) and node.value in names]
    assert found == []


def test_a_grid_only_method_is_refused_on_a_gmsh_mesh(monkeypatch):
    """A method without the ``unstructured`` capability: a mesh case stops at load (exit 2)."""
    from dataclasses import replace

    from fem_runout import methods
    from fem_runout.config import load_case
    from fem_runout.errors import CaseError

    grid_only = replace(methods.get("mpm"), name="grid_only", display="GridOnly",
                        unstructured=False)
    monkeypatch.setitem(methods.METHODS, "grid_only", grid_only)
    with pytest.raises(CaseError, match="method: GridOnly runs on the rectangle's grid only"):
        load_case(ROOT / "cases" / "curved_channel.yaml", [("method", "grid_only")])
    load_case(ROOT / "cases" / "curved_channel.yaml", [("method", "mpm")])  # both run on it
