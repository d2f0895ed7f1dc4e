"""Manning sheet: a uniform layer sliding down a uniform slope with Manning friction.

Manning's bed shear (:mod:`fem_runout.physics.friction.manning`, in place of seed eq. 2) on a
layer of uniform depth and velocity leaves no pressure or depth gradient, so the momentum
balance is an ODE, solved exactly as for the Voellmy sheet (:mod:`.voellmy_sheet`):

**Horizontal form** (seed eq. 1, ``model.form: horizontal``) on ``Z = -S x`` with vertical
depth ``h``: the source ``g h S`` against ``g n² u²/h^{1/3}`` gives::

    du/dt = g S - g n² u²/h^{4/3} = a - b u²,   a = g S,  b = g n²/h^{4/3}
    u(t) = sqrt(a/b) tanh(sqrt(a b) t)            (u(0) = 0)

with the uniform-flow speed of Manning's formula ``u_∞ = sqrt(a/b) = h^{2/3} S^{1/2}/n``.

**Slope-consistent form** (``model.form: slope``, :mod:`fem_runout.physics.slope`) on a plane
of angle θ with slope-normal thickness ``h_n`` (vertical depth ``h_n/cosθ``): the horizontal
momentum gets ``G h tanθ = g cos²θ h tanθ`` from the bed term and loses
``g_t n² u²/h_n^{1/3}`` with ``g_t = g s/cosθ = g/cos²θ`` (``s = 1/cosθ`` straight down the
slope); with ``u = U cosθ`` (``U`` the speed along the bed) this is::

    dU/dt = g sinθ - g n² U²/h_n^{4/3},   U(t) = U_∞ tanh(t/τ),
    U_∞ = h_n^{2/3} (sinθ)^{1/2}/n,  τ = h_n^{2/3}/(g n (sinθ)^{1/2})

(Manning's formula with the hydraulic radius ``h_n`` of a wide sheet and the friction slope
``sinθ``). Both forms are the same law; they differ in what ``h`` and the slope are.
"""

from __future__ import annotations

import math

from fem_runout.references.voellmy_sheet import strip_case

#: Horizontal-form sheet: slope S, roughness n [s/m^(1/3)], vertical depth [m].
SLOPE, N, H = 0.3, 0.05, 1.0
#: Measured here (the boundaries' disturbances have not reached it by :func:`case_dict`'s end).
WINDOW = (250.0, 350.0)
#: Slope-form sheet: angle [deg], roughness, slope-normal thickness [m].
THETA, SLOPE_N, H_N = 35.0, 0.05, 1.0
SLOPE_WINDOW = (450.0, 650.0)
#: Relaxation times to the end of a run: ``tanh(4) = 0.99933``, the sheet is in uniform flow.
RELAXATIONS = 4.0


def _tanh_law(t: float, a: float, b: float) -> float:
    """``sqrt(a/b) tanh(sqrt(a b) t)``: the speed of ``du/dt = a - b u²`` from rest."""
    return math.sqrt(a / b) * math.tanh(math.sqrt(a * b) * t)


def speed(t: float, slope: float = SLOPE, n: float = N, h: float = H,
          g: float = 9.81) -> float:
    """Exact speed [m/s] of the horizontal-form sheet at time ``t`` from rest."""
    return _tanh_law(t, g * slope, g * n * n / h ** (4.0 / 3.0))


def terminal_speed(slope: float = SLOPE, n: float = N, h: float = H) -> float:
    """Uniform-flow speed ``u_∞ = h^{2/3} S^{1/2}/n`` [m/s] (Manning's formula)."""
    return h ** (2.0 / 3.0) * math.sqrt(slope) / n


def relaxation_time(slope: float = SLOPE, n: float = N, h: float = H, g: float = 9.81) -> float:
    """``1/sqrt(a b) = h^{2/3}/(g n S^{1/2})`` [s]."""
    return h ** (2.0 / 3.0) / (g * n * math.sqrt(slope))


def slope_speed(t: float, theta_deg: float = THETA, n: float = SLOPE_N, h_n: float = H_N,
                g: float = 9.81) -> float:
    """Exact speed along the bed ``U(t)`` [m/s] of the slope-form sheet from rest."""
    return _tanh_law(t, g * math.sin(math.radians(theta_deg)), g * n * n / h_n ** (4.0 / 3.0))


def slope_terminal_speed(theta_deg: float = THETA, n: float = SLOPE_N,
                         h_n: float = H_N) -> float:
    """``U_∞ = h_n^{2/3} (sinθ)^{1/2}/n`` [m/s] along the bed."""
    return h_n ** (2.0 / 3.0) * math.sqrt(math.sin(math.radians(theta_deg))) / n


def slope_relaxation_time(theta_deg: float = THETA, n: float = SLOPE_N, h_n: float = H_N,
                          g: float = 9.81) -> float:
    """``τ = h_n^{2/3}/(g n (sinθ)^{1/2})`` [s]."""
    return h_n ** (2.0 / 3.0) / (g * n * math.sqrt(math.sin(math.radians(theta_deg))))


def case_dict(cells: int, g: float = 9.81) -> dict:
    """Horizontal form: 1 m layer on Z = -0.3 x, n = 0.05, 400 m × 4 m, to 4 relaxation times.

    ``u_∞ = 10.95 m/s``, ``τ = 3.72 s``. Disturbances travel at most ``|u| + sqrt(g h)``
    (< 14.1 m/s), 210 m from the upstream wall in ``4 τ``; the downstream open side is
    supercritical after 1 s. So :data:`WINDOW` keeps the uniform layer of the exact solution.
    """
    end = RELAXATIONS * relaxation_time(g=g)
    return strip_case("manning_sheet", cells, 400.0, f"-{SLOPE} * x", str(H),
                      {"law": "manning", "n": N}, end, g, form="horizontal")


def slope_case(cells: int, g: float = 9.81) -> dict:
    """Slope form: 1 m (slope-normal) sheet on 35°, n = 0.05, 800 m × 4 m, to 4 τ.

    ``U_∞ = 15.1 m/s``, ``τ = 2.69 s``; disturbances from the upstream wall travel at most
    ``u + sqrt(G h)`` < 16 m/s horizontally (175 m in ``4 τ``), so :data:`SLOPE_WINDOW`
    keeps the uniform layer.
    """
    th = math.radians(THETA)
    end = RELAXATIONS * slope_relaxation_time(g=g)
    return strip_case("manning_slope", cells, 800.0, f"-{math.tan(th)!r} * x",
                      repr(H_N / math.cos(th)), {"law": "manning", "n": SLOPE_N}, end, g,
                      form="slope")
