"""Compiled passes over compact arrays: the bits of the array formulas they replace."""

import numpy as np
import pytest

from fem_runout.physics.slope import SlopeGeometry
from fem_runout.tg2 import compact
from fem_runout.tg2.low_order import low_order_pass, pair_norms, velocity, velocity_on
from fem_runout.tg2.mass_correction import rates_and_sensor


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Bitwise equality (signed zeros and NaN payloads included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def _data(rng, shape):
    """Random values with exact zeros, signed zeros and tiny magnitudes mixed in."""
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-12, 3, size=shape)
    flat = x.reshape(-1)
    flat[rng.random(flat.size) < 0.1] = 0.0
    flat[rng.random(flat.size) < 0.05] = -0.0
    return x


@pytest.mark.parametrize("seed", range(3))
def test_state_passes_give_the_array_formulas_bits(seed):
    rng = np.random.default_rng(seed)
    n, cells = 50, 30
    q_low, corr, sums, boundary = (_data(rng, (n, 3)) for _ in range(4))
    m = rng.uniform(0.1, 100.0, n)
    high, lo = _data(rng, (cells, 4, 3)), _data(rng, (cells, 4, 4))[:, :, :3]  # a strided view
    dt = 0.37
    assert _same(compact.antidiffusive(high, lo, dt, np.empty((cells, 4, 3))), high - dt * lo)
    assert _same(compact.new_state(q_low, corr, m), q_low + corr / m[:, None])
    assert _same(compact.low_state(q_low, sums, boundary, m, dt),
                 q_low + dt * (sums + boundary) / m[:, None])


def test_velocity_on_a_subset_writes_the_same_velocities():
    rng = np.random.default_rng(4)
    h = np.abs(_data(rng, 60)) * rng.choice([1.0, -1.0], 60)  # some round-off negative depths
    hu, hv = _data(rng, 60), _data(rng, 60)
    nodes = np.sort(rng.permutation(60)[:40])
    ref_x, ref_y = np.empty(40), np.empty(40)
    velocity(h[nodes], hu[nodes], hv[nodes], 1e-3, ref_x, ref_y)
    ux, uy = np.full(60, 7.0), np.full(60, 7.0)
    on_x, on_y = np.empty(40), np.empty(40)
    velocity_on(h, hu, hv, nodes, 1e-3, ux, uy, on_x, on_y)
    assert _same(on_x, ref_x) and _same(on_y, ref_y)
    assert _same(ux[nodes], ref_x) and _same(uy[nodes], ref_y)
    others = np.setdiff1d(np.arange(60), nodes)
    assert np.all(ux[others] == 7.0) and np.all(uy[others] == 7.0)  # the others untouched


def test_low_order_pass_overwrites_its_capacities():
    """Capacities full of garbage give the rates and capacities of a zeroed buffer."""
    rng = np.random.default_rng(5)
    cells = np.array([[0, 1, 3, 4], [1, 2, 4, 5], [3, 4, 6, 7], [4, 5, 7, 8]])
    h = rng.uniform(0.0, 2.0, 9)
    hu, hv, z = rng.normal(size=9), rng.normal(size=9), rng.normal(size=9)
    beta, C = rng.normal(size=(4, 6, 2)), rng.normal(size=(4, 4, 4, 2))
    ux, uy = np.empty(9), np.empty(9)
    velocity(h, hu, hv, 1e-3, ux, uy)
    norms = pair_norms(beta)
    assert _same(norms, np.sqrt(np.square(beta).sum(axis=2)))
    results = []
    for fill in (0.0, np.nan):
        out, cap = np.full((4, 4, 3), fill), np.full((4, 4), fill)
        low_order_pass(cells, beta, norms, C, h, hu, hv, z, ux, uy, np.full(9, 9.81), 1e-3,
                       out, cap)
        results.append((out, cap))
    assert _same(results[0][0], results[1][0]) and _same(results[0][1], results[1][1])
    assert np.all(results[0][1] > 0.0)  # every node of a wet patch has a capacity


def test_normal_acceleration_is_the_formula():
    rng = np.random.default_rng(6)
    n = 40
    hess, grad = rng.normal(size=(n, 3)), rng.normal(size=(n, 2))
    ux, uy = rng.normal(size=n) * 20.0, rng.normal(size=n) * 20.0
    ux[0] = np.nan
    geom = SlopeGeometry(grad, hess, 9.81)
    hxx, hxy, hyy = hess[:, 0], hess[:, 1], hess[:, 2]
    ref = np.maximum(9.81 + (ux * (hxx * ux + hxy * uy) + uy * (hxy * ux + hyy * uy)), 0.0)
    got = geom.normal_acceleration(ux, uy)
    assert _same(got, ref) and np.isnan(got[0]) and np.any(got == 0.0)
    assert _same(geom.pressure_gravity(ux, uy), geom.cos2 * ref)


def test_rates_and_sensor_are_the_formulas():
    rng = np.random.default_rng(7)
    sums, boundary = _data(rng, (30, 5)), _data(rng, (30, 3))
    mass = rng.uniform(0.1, 10.0, 30)
    dq, sensor = np.empty((30, 3)), np.empty(30)
    rates_and_sensor(sums, boundary, mass, 1e-3, dq, sensor)
    assert _same(dq, (sums[:, :3] + boundary) / mass[:, None])
    assert _same(sensor, np.abs(sums[:, 3]) / (sums[:, 4] + 1e-3))


def test_a_snapshot_of_the_flows_nodes_restores_the_whole_state():
    """TG2-PC's snapshot keeps the active set's rows only (zero elsewhere) and restores all."""
    from mpi4py import MPI

    from fem_runout.api import build_solver
    from tests.tg2_helpers import case

    def solver():
        return build_solver(case("hemisphere", "method=tg2", "domain.cells=[32,32]",
                                 "material.friction.law=voellmy", "material.friction.mu=0.2",
                                 "material.friction.xi=500"), MPI.COMM_SELF)

    s, twin = solver(), solver()
    dts = []
    for _ in range(3):
        dts.append(0.9 * s.stable_dt())
        s.advance(dts[-1])
        twin.advance(dts[-1])
    snap = s.snapshot()
    nodes = snap[0]
    assert nodes is not None and 0 < nodes.size < s.fields["h"].x.array.size
    for _ in range(4):  # the flow moves on (and the set with it), then the run goes back
        s.advance(0.9 * s.stable_dt())
    s.restore(snap)
    for key in ("h", "hu", "hv"):
        assert _same(s.fields[key].x.array, twin.fields[key].x.array), key
    dt = 0.9 * twin.stable_dt()
    assert s.stable_dt() == twin.stable_dt()
    s.advance(dt)
    twin.advance(dt)
    for key in ("h", "hu", "hv"):
        assert _same(s.fields[key].x.array, twin.fields[key].x.array), key


def test_reductions_and_ramps_are_the_formulas():
    from fem_runout.physics.slope import BedFrame, downhill
    from fem_runout.tg2.limiter import thin_ramp

    rng = np.random.default_rng(8)
    m, c = rng.uniform(0.1, 9.0, 40), _data(rng, 40)
    n = 30
    own_m, own_c = m[:n], c[:n]
    assert compact.min_ratio(m, c, n) == np.min(own_m[own_c > 0.0] / own_c[own_c > 0.0])
    assert compact.min_ratio(m, -np.abs(c), n) == np.inf
    h, s = _data(rng, 40), np.abs(_data(rng, 40))
    ref = np.max(s[:n] * np.clip(h[:n] / 0.05, 0.0, 1.0))
    assert compact.wet_weighted_max(h, s, 0.05, n) == ref
    assert compact.wet_weighted_max(h, s, 0.05, 0) == 0.0
    near, far = np.abs(_data(rng, 40)), _data(rng, 40)
    out = np.empty(40)
    thin_ramp(near, far, 1e-3, 0.1, out)
    assert _same(out, np.clip(near / (1e-3 + 0.1 * np.maximum(far, 0.0)), 0.0, 1.0))
    grad = _data(rng, (40, 2))
    grad[3] = 0.0
    ref = -grad / np.maximum(np.hypot(grad[:, 0], grad[:, 1]), 1e-300)[:, None]
    assert _same(downhill(grad), ref) and np.all(downhill(grad)[3] == 0.0)
    frame = BedFrame(grad, np.ones(40), np.ones(40))
    assert _same(frame.downhill(), ref) and _same(frame.take(np.arange(5, 9)).downhill(), ref[5:9])
    geometry = SlopeGeometry(grad, np.zeros((40, 3)), 9.81)
    first = geometry.frame().downhill()
    assert _same(first, ref) and geometry.frame().downhill() is first  # formed once


def test_envelopes_fold_like_the_array_formulas():
    from fem_runout.output.diagnostics import nodal_speed
    from fem_runout.output.envelopes import fold_envelopes

    rng = np.random.default_rng(9)
    n, thr, rho, t = 60, 0.01, 200.0, 12.5
    h = np.abs(_data(rng, n))
    h[:5] = [0.0, -0.0, 0.01, 0.02, 1e-9]
    hu, hv = _data(rng, n), _data(rng, n)
    nodes = np.sort(rng.permutation(n)[:45])
    start = {"depth": np.abs(_data(rng, n)), "speed": np.abs(_data(rng, n)),
             "pressure": np.abs(_data(rng, n)),
             "arrival": np.where(rng.random(n) < 0.5, np.nan, 3.0)}
    start["depth"][nodes[:3]] = h[nodes[:3]]  # ties
    ref = {k: v.copy() for k, v in start.items()}
    speed = nodal_speed(h[nodes], hu[nodes], hv[nodes], thr)
    ref["depth"][nodes] = np.maximum(ref["depth"][nodes], h[nodes])
    ref["speed"][nodes] = np.maximum(ref["speed"][nodes], speed)
    ref["pressure"][nodes] = np.maximum(ref["pressure"][nodes], rho * speed**2)
    arrival = ref["arrival"][nodes]
    arrival[np.isnan(arrival) & (h[nodes] > thr)] = t
    ref["arrival"][nodes] = arrival
    got = {k: v.copy() for k, v in start.items()}
    fold_envelopes(nodes, h, hu, hv, thr, got["depth"], got["speed"], got["pressure"],
                   got["arrival"], t, rho)
    for key in ref:
        assert _same(got[key], ref[key]), key
    only = {k: start[k].copy() for k in ("depth", "speed")}
    fold_envelopes(nodes, h, hu, hv, thr, only["depth"], only["speed"])
    assert _same(only["depth"], ref["depth"]) and _same(only["speed"], ref["speed"])


@pytest.mark.parametrize("energy", [True, False])
def test_motion_terms_are_the_formulas(energy):
    """The runner's speed and kinetic-energy terms (one pass) against the array formulas."""
    from fem_runout.health import motion_terms

    rng = np.random.default_rng(10)
    n = 80
    h, hu, hv, m = np.abs(_data(rng, n)), _data(rng, n), _data(rng, n), rng.uniform(1, 9, n)
    nodes = np.sort(rng.permutation(n)[:60])
    depth = 0.01
    wet = h[nodes] > depth
    q2 = hu[nodes][wet] ** 2 + hv[nodes][wet] ** 2
    terms = np.empty(nodes.size if energy else 0)
    top, big, k = motion_terms(nodes, h, hu, hv, m, depth, energy, terms)
    assert top == np.max(q2 / h[nodes][wet] ** 2)
    if energy:
        ref = m[nodes][wet] * q2 / h[nodes][wet]
        assert k == wet.sum() and _same(terms[:k], ref) and big == np.max(ref, initial=0.0)
    else:
        assert k == 0 and big == 0.0
    assert motion_terms(nodes, np.zeros(n), hu, hv, m, depth, energy, terms)[:3:2] == \
        (-np.inf, 0)
    hu[nodes[wet.argmax()]] = np.nan  # a NaN wins, as in np.max
    assert np.isnan(motion_terms(nodes, h, hu, hv, m, depth, energy, terms)[0])
