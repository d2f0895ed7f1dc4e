"""The registry of numerical methods: the one place that names them.

Every other module (case schema, CLI, ``compare``, bench, reports) reads this registry; no
method name is written anywhere else in the code. A method is a :class:`Method`: its key in
case files, a display name, the builder that turns a validated case into a
:class:`~fem_runout.solver_api.Solver`, what it can do, and the seed paper's reference values
for it. Adding a method is one :func:`register` call (docs/extending.md).

The builder is named as ``"module:function"`` and imported only when a run needs it, so that
reading the registry (the schema does, at import) loads no solver code.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mpi4py import MPI

    from fem_runout.config import Case
    from fem_runout.solver_api import Solver

__all__ = ["METHODS", "Method", "default_method", "get", "method_names", "register"]


@dataclass(frozen=True)
class Method:
    """A numerical method.

    Attributes:
        name: Key in case files (``method: <name>``) and on the command line.
        display: Name in reports, pictures and tables.
        builder: ``"module:function"``; the function is ``(case, comm) -> Solver``.
        particles: The method carries material points (particle counts).
        outputs: Output callbacks of the method's own, as ``"module:Class"``; each class is
            called with the output folder (imported only when a run writes one).
        rheology: The method supports an internal rheology (``material.rheology``).
        unstructured: The method runs on gmsh meshes (``domain.outline``, ``domain.mesh``),
            not only on the rectangle's grid.
        step_bounds: The method reads ``numerics.step_bound`` (its time step's bound can be
            the depth's own, ``positivity``; the peers' bench adds such a row).
        description: One line for ``--help`` and docs.
        paper: The seed paper's reported values for this method (e.g. ``front`` on the
            inclined dam break: time [s] -> front [m]; ``lake``: variable -> (L1, L∞) of
            seed Table 2, as printed).
        marker: Matplotlib (colour, marker) for figures.
    """

    name: str
    display: str
    builder: str
    particles: bool = False
    outputs: tuple[str, ...] = ()
    rheology: bool = True
    unstructured: bool = True
    step_bounds: bool = False
    description: str = ""
    paper: Mapping[str, Any] = field(default_factory=dict)
    marker: tuple[str, str] = ("tab:gray", "x")

    def build(self, case: Case, comm: MPI.Comm) -> Solver:
        """Build the solver of ``case`` (collective)."""
        module, name = self.builder.split(":")
        factory: Callable[..., Solver] = getattr(importlib.import_module(module), name)
        return factory(case, comm)

    def output_callbacks(self, out_dir: Path) -> list[Any]:
        """Return the method's own output callbacks (:attr:`outputs`) for ``out_dir``."""
        made = []
        for spec in self.outputs:
            module, name = spec.split(":")
            made.append(getattr(importlib.import_module(module), name)(out_dir))
        return made


#: name -> Method, in registration order (the first is the default).
METHODS: dict[str, Method] = {}


def register(method: Method) -> Method:
    """Add ``method`` to the registry (its name must be new)."""
    if method.name in METHODS:
        raise ValueError(f"method '{method.name}' is already registered")
    METHODS[method.name] = method
    return method


def get(name: str) -> Method:
    """Return the method called ``name`` (KeyError listing the registered names if none)."""
    try:
        return METHODS[name]
    except KeyError:
        raise KeyError(f"unknown method '{name}'; available: {', '.join(METHODS)}") from None


def method_names() -> tuple[str, ...]:
    """Return the registered method names, the default first."""
    return tuple(METHODS)


def default_method() -> str:
    """Name of the default method (the first registered)."""
    return next(iter(METHODS))


register(Method(
    name="tg2",
    display="TG2-PC",
    builder="fem_runout.tg2.solver:build_tg2",
    step_bounds=True,
    description="two-step Taylor-Galerkin with path-conservative edge terms and FCT (seed §3.1)",
    paper={"front": {5.5: 97.3, 11.0: 240.6},
           "lake": {"h": ("2.68e-13", "8.92e-15"), "hu": ("2.38e-13", "1.41e-14"),
                    "hv": ("1.67e-13", "2.02e-14")}},
    marker=("tab:blue", "o"),
))
register(Method(
    name="mpm",
    display="DAMPM",
    builder="mpm.build:build_mpm",
    particles=True,
    outputs=("mpm.output:ParticleWriter",),
    description="depth-averaged material point method (seed §3.2)",
    paper={"front": {5.5: 96.2, 11.0: 239.2},
           "lake": {"h": ("1.26e-12", "1.26e-14"), "hu": ("1.08e-13", "3.57e-14"),
                    "hv": ("1.22e-13", "3.25e-14")}},
    marker=("tab:red", "s"),
))
