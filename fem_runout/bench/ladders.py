"""Benchmark definitions: one refinement ladder per reference, each level measured per method.

Each :class:`Benchmark` runs a level with :func:`fem_runout.api.run` (collective) and returns a
:class:`Level`: the error against its reference in the benchmark's stated norm, plus cells,
particles (``RunResult.particles`` if the method sets it), steps and wall time of the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

CASES = Path(__file__).resolve().parents[2] / "cases"


@dataclass
class Level:
    """One measured level (JSON-serialisable)."""

    level: str
    cells: int
    particles: int | None
    steps: int
    wall: float
    error: float
    extra: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """As a plain dict."""
        return asdict(self)


@dataclass(frozen=True)
class Benchmark:
    """A reference and its ladder.

    Attributes:
        name: Short name (figure file ``bench_<name>.png``).
        title: Section title.
        norm: The error measure, in words.
        reference: Formula and source, in words (markdown).
        levels: Level parameters, coarse to fine.
        measure: ``measure(param, method, comm) -> Level``.
        claims_order: Whether an observed order is reported.
    """

    name: str
    title: str
    norm: str
    reference: str
    levels: tuple[Any, ...]
    measure: Callable[[Any, str, Any], Level]
    claims_order: bool = True


def _run(source, method: str, comm, overrides: tuple = ()):
    from fem_runout.api import run
    from fem_runout.config import load_case

    case = load_case(source, [*overrides, ("method", method)])
    return case, run(case, write=False, comm=comm)


def _level(label: str, case, r, error: float, **extra: float) -> Level:
    nx, ny = case.domain.resolved_cells
    return Level(label, nx * ny, getattr(r, "particles", None), r.steps, r.wall_time,
                 float(error), {k: float(v) for k, v in extra.items()})


def _bcast(comm, value):
    return comm.bcast(value, root=0)


def ritter(nx: int, method: str, comm) -> Level:
    """L1 of h per metre of width at t = 4 s."""
    from fem_runout.references.norms import l1, nodal_weights
    from fem_runout.references.ritter import ritter_depth

    case, r = _run(CASES / "ritter.yaml", method, comm,
                   (f"domain.cells=[{nx},2]", "output.every=4.0"))
    err = None
    if r.x is not None:
        err = l1(r.h - ritter_depth(r.x, r.t, 1.0, 50.0, case.gravity),
                 nodal_weights(r.x, r.y)) / 2.0
    return _level(f"{nx}×2", case, r, _bcast(comm, err))


def stoker(nx: int, method: str, comm, h_r: float = 0.1) -> Level:
    """Relative L1 of h at t = 2 s, dam at x0 = 50 m (the 2-rank partition cut at 400 cells)."""
    from fem_runout.references.norms import l1, nodal_weights
    from fem_runout.references.stoker import dam_break_case, exact_depth

    case, r = _run(dam_break_case(1.0, h_r, 50.0, (nx, 4), 2.0, method), method, comm)
    err, low = None, None
    if r.x is not None:
        exact = exact_depth(r.x, r.t, 1.0, h_r, 50.0, case.gravity)
        w = nodal_weights(r.x, r.y)
        err, low = l1(r.h - exact, w) / l1(exact, w), float(r.h.min())
    return _level(f"{nx}×4", case, r, _bcast(comm, err), min_h=_bcast(comm, low))


def stoker_100(nx: int, method: str, comm) -> Level:
    """As :func:`stoker` with the depth ratio 100:1."""
    return stoker(nx, method, comm, h_r=0.01)


def thacker(n: int, method: str, comm, periods: float = 1.0) -> Level:
    """L1 of h on the disc 0.2 m inside the wet/dry line; full-domain L1 as extra."""
    from fem_runout.references import thacker as ref
    from fem_runout.references.norms import l1, nodal_weights

    case, r = _run(ref.case_dict(n, periods), method, comm)
    vals = None
    if r.x is not None:
        exact = ref.depth(r.x, r.y, r.t, case.gravity)
        w = nodal_weights(r.x, r.y)
        wt = ref.omega(case.gravity) * r.t
        rho = np.hypot(r.x - ref.L / 2 - ref.ETA * math.cos(wt),
                       r.y - ref.L / 2 - ref.ETA * math.sin(wt))
        err = r.h - exact
        bands = [(rho >= a) & (rho < b) for a, b in ((0, 0.25), (0.25, 0.5), (0.5, 0.8))]
        vals = (l1(err[rho <= 0.8 * ref.A], w[rho <= 0.8 * ref.A]), l1(err, w),
                *(l1(err[b], w[b]) for b in bands))
    vals = _bcast(comm, vals)
    return _level(f"{n}×{n}", case, r, vals[0], full_l1=vals[1], l1_rho_0_025=vals[2],
                  l1_rho_025_05=vals[3], l1_rho_05_08=vals[4])


def thacker_two_periods(n: int, method: str, comm) -> Level:
    """:func:`thacker` after two periods."""
    return thacker(n, method, comm, periods=2.0)


def mangeney(nx: int, method: str, comm) -> Level:
    """L1 of h (per metre of width) where the upstream wall has not yet disturbed the flow."""
    from fem_runout.references import mangeney as ref

    case, r, err, front = _incline(
        ref.case_dict(nx), method, comm,
        lambda x, t, g: ref.depth(x, t, ref.H0, ref.X0, ref.SLOPE, ref.MU, g),
        lambda t, g: ref.valid_from(t, ref.H0, ref.SLOPE, ref.MU, 0.0, g))
    exact = ref.front(r.t, ref.H0, ref.X0, ref.SLOPE, ref.MU, case.gravity)
    return _level(f"{nx}×2", case, r, err, front=front, exact_front=exact)


def _incline(case_dict: dict, method: str, comm, exact, valid_from, scale: float = 1.0):
    """Run a dam break on an incline: ``(case, result, L1 of h where valid, front × scale)``."""
    from fem_runout.references.norms import l1, nodal_weights

    case, r = _run(case_dict, method, comm)
    vals = None
    if r.x is not None:
        g = case.gravity
        keep = r.x >= valid_from(r.t, g) + 1.0
        wet = r.x[r.h > 1e-3]
        vals = (l1((r.h - exact(r.x, r.t, g))[keep], nodal_weights(r.x, r.y)[keep]),
                float(wet.max()) * scale if wet.size else math.nan)
    vals = _bcast(comm, vals)
    return case, r, vals[0], vals[1]


def voellmy_sheet(nx: int, method: str, comm) -> Level:
    """Relative error of the sheet speed (mean over the window) at 3 relaxation times."""
    from fem_runout.references import voellmy_sheet as ref

    return _sheet(nx, method, comm, ref.case_dict(nx), ref.WINDOW,
                  lambda t, g: ref.speed(t, 0.3, 0.1, 500.0, 1.0, g))


def manning_sheet(nx: int, method: str, comm) -> Level:
    """Relative error of the Manning sheet's speed (mean over the window) at 4 relaxation times.

    Horizontal form; the exact speed is then within 7e-4 of the uniform-flow speed
    ``h^{2/3} S^{1/2}/n`` (:mod:`fem_runout.references.manning_sheet`).
    """
    from fem_runout.references import manning_sheet as ref

    return _sheet(nx, method, comm, ref.case_dict(nx), ref.WINDOW,
                  lambda t, g: ref.speed(t, g=g))


def manning_slope(nx: int, method: str, comm) -> Level:
    """As :func:`manning_sheet` in the slope form: the speed along the bed on 35°."""
    from fem_runout.references import manning_sheet as ref

    return _sheet(nx, method, comm, ref.slope_case(nx), ref.SLOPE_WINDOW,
                  lambda t, g: ref.slope_speed(t, g=g),
                  1.0 / math.cos(math.radians(ref.THETA)))


def _sheet(nx: int, method: str, comm, case_dict: dict, window: tuple[float, float],
           exact, scale: float = 1.0) -> Level:
    """Relative error of a sliding sheet's mean speed on ``window`` (× ``scale``)."""
    case, r = _run(case_dict, method, comm)
    err = None
    if r.x is not None:
        win = (r.x >= window[0]) & (r.x <= window[1])
        speed = float(np.mean(r.hu[win] / r.h[win])) * scale
        ref_speed = exact(r.t, case.gravity)
        err = (abs(speed / ref_speed - 1.0), speed, ref_speed)
    err = _bcast(comm, err)
    return _level(f"{nx}×2", case, r, err[0], speed=err[1], exact=err[2])


def shear_decay(ny: int, method: str, comm) -> Level:
    """Relative error of the decay rate of the viscous shear mode after 1 s."""
    from fem_runout.references import shear_decay as ref

    case, r = _run(ref.case_dict(ny), method, comm)
    err = None
    if r.x is not None:
        rate = ref.measured_rate(r.x, r.y, r.h, r.hu, r.t)
        exact = ref.decay_rate(500.0, 1000.0)
        err = (abs(rate / exact - 1.0), rate, exact)
    err = _bcast(comm, err)
    return _level(f"40×{ny}", case, r, err[0], rate=err[1], exact=err[2])


DAM_TIMES = (5.5, 11.0)


def dam_break(nx: int, method: str, comm, rows: int | None = None) -> Level:
    """Relative front error at 11 s (seed Table 1 measure); fronts at 2.75 … 11 s as extras.

    Args:
        nx: cells along the 450 m channel; ``nx // 22`` (at least 2) across its 20 m.
        method: registered method name.
        comm: communicator of the run.
        rows: run a strip of the channel this many cells wide instead, with the same cells
            (the flow does not depend on y and the sides are walls: the same nodal depths,
            fronts and steps at a fraction of the cost; for tests).
    """
    from fem_runout.references.inclined_dam_break import exact_front

    ny = max(2, nx // 22)
    strip = () if rows is None else (f"domain.extent=[0, 450, 0, {20.0 * rows / ny!r}]",)
    case, r = _run(CASES / "inclined_dam_break_450.yaml", method, comm,
                   (f"domain.cells=[{nx},{ny if rows is None else rows}]", *strip,
                    "output.every=5.5"))
    s = r.series
    fronts = {f"front_{t}": float(s["front_x"][int(np.argmin(np.abs(s["t"] - t)))])
              for t in DAM_TIMES}
    rel = {f"rel_{t}": abs(fronts[f"front_{t}"] / exact_front(t) - 1.0) for t in DAM_TIMES}
    return _level(f"{nx}×{ny}", case, r, rel["rel_11.0"], front_5_5=fronts["front_5.5"],
                  front_11=fronts["front_11.0"], rel_5_5=rel["rel_5.5"])


def hemisphere(n: int, method: str, comm) -> Level:
    """Relative L1 error of h at 1.2 s against the converged radial solution.

    Extras: the front radius along x, y, −x and the diagonal, their spread (isotropy) and the
    largest distance of one from the reference's front (:mod:`fem_runout.references.radial`).
    """
    from fem_runout.references.norms import front_radius, nodal_weights
    from fem_runout.references.radial import hemisphere_errors

    case, r = _run(CASES / "hemisphere.yaml", method, comm, (f"domain.cells=[{n},{n}]",))
    vals = None
    if r.x is not None:
        dirs = {"r_x": (1, 0), "r_y": (0, 1), "r_mx": (-1, 0),
                "r_diag": (math.sqrt(0.5), math.sqrt(0.5))}
        vals = {k: front_radius(r.x, r.y, r.h, (25.0, 25.0), 1e-3, d) for k, d in dirs.items()}
        vals["spread"] = max(vals.values()) - min(vals.values())
        vals.update(hemisphere_errors(r.x, r.y, r.h, nodal_weights(r.x, r.y), (25.0, 25.0),
                                      r.t, case.gravity, radii={k: vals[k] for k in dirs}))
    vals = _bcast(comm, vals)
    return _level(f"{n}×{n}", case, r, vals.pop("l1"), **vals)


def lake_at_rest(n: int, method: str, comm) -> Level:
    """L1 of the free-surface error on wet nodes, seed §4.2 with Voellmy friction and Bingham."""
    from fem_runout.references.norms import l1, linf, nodal_weights

    case, r = _run(CASES / "lake_at_rest.yaml", method, comm, (
        f"domain.cells=[{n},{n}]", "material.friction={law: voellmy, phi_deg: 26, xi: 500}",
        "material.rheology={law: bingham, viscosity: 2000, yield_stress: 30}"))
    vals = None
    if r.x is not None:
        w = nodal_weights(r.x, r.y)
        eta = np.where(r.h > 1e-6, r.h + r.z - 10.0, 0.0)
        vals = {"h_l1": l1(eta, w), "h_linf": linf(eta), "hu_l1": l1(r.hu, w),
                "hu_linf": linf(r.hu), "hv_l1": l1(r.hv, w), "hv_linf": linf(r.hv)}
    vals = _bcast(comm, vals)
    return _level(f"{n}×{n}", case, r, vals["h_l1"], **vals)


def voellmy_slope(nx: int, method: str, comm) -> Level:
    """Relative error of the speed along the bed on the window, at 3 relaxation times."""
    from fem_runout.references import slope as ref

    return _sheet(nx, method, comm, ref.sheet_case(nx), ref.SHEET_WINDOW,
                  lambda t, g: ref.sheet_speed(t, g=g),
                  1.0 / math.cos(math.radians(ref.SHEET_THETA)))


def energy_line(nx: int, method: str, comm) -> Level:
    """``|tan α / μ − 1|`` of the block's centre of mass once at rest."""
    from fem_runout.references import slope as ref
    from fem_runout.references.norms import nodal_weights

    case, r = _run(ref.line_case(nx), method, comm)
    vals = None
    if r.x is not None:
        w = nodal_weights(r.x, r.y)
        x0, x1, h = ref.LINE_BLOCK
        h0 = np.where((r.x > x0) & (r.x < x1), h, 0.0)
        tan = ref.travel_tangent(r.x, h0, r.x, r.h, w)
        vals = (abs(tan / ref.LINE_MU - 1.0), tan, float(r.t))
    vals = _bcast(comm, vals)
    return _level(f"{nx}×2", case, r, vals[0], tan_alpha=vals[1], stop_time=vals[2])


def mangeney_slope(nx: int, method: str, comm) -> Level:
    """L1 of the vertical depth per metre of width at t = 2 s, away from the upstream wall."""
    from fem_runout.references import slope as ref

    case, r, err, front = _incline(ref.mangeney_case(nx), method, comm,
                                   lambda x, t, g: ref.mangeney_depth(x, t, g),
                                   ref.mangeney_valid_from,
                                   1.0 / math.cos(math.radians(ref.MANG_THETA)))
    ours, sh = ref.mangeney_fronts(r.t, case.gravity)
    return _level(f"{nx}×2", case, r, err, front_along_slope=front, exact_front=ours,
                  savage_hutter_front=sh)
