"""The case file schema: frozen pydantic models with defaults and checks.

Every model forbids unknown keys. Expressions are checked when the case is
validated and stored as source strings; ``*_fn()`` helpers return compiled
:class:`~fem_runout.config.expr.Expression` objects.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator, Field, PrivateAttr, model_validator

from fem_runout.config.domain import BoundarySides, DomainSpec
from fem_runout.config.expr import Expression, compile_expression
from fem_runout.config.geo import ReleaseArea, TerrainSpec, expand_data_path, parse_release
from fem_runout.config.material import FrictionSpec, MaterialSpec, RheologySpec
from fem_runout.config.timing import TimeSpec
from fem_runout.config.types import Bool, Expr, Int, Real, SpecError, StrictSpec, is_number
from fem_runout.methods import default_method, method_names

__all__ = [
    "BoundarySides",
    "Case",
    "DomainSpec",
    "FrictionSpec",
    "InitialSpec",
    "MaterialSpec",
    "ModelSpec",
    "NumericsSpec",
    "OutputSpec",
    "ReleaseArea",
    "RheologySpec",
    "SpecError",
    "TerrainSpec",
    "TimeSpec",
]


def _method(value: Any) -> Any:
    names = method_names()
    if value not in names:
        raise SpecError(f"must be one of {', '.join(names)} (the registered methods, "
                        f"fem_runout/methods.py), got {value!r}")
    return value


def _velocity(value: Any) -> Any:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise SpecError(f"must be two expressions [u, v], got {value!r}")
    return tuple(value)


class InitialSpec(StrictSpec):
    """Initial state: depth ``h``, free surface ``h + z`` or release areas [m]; velocity [m/s]."""

    depth: Expr | None = None
    free_surface: Expr | None = None
    release: Annotated[tuple[ReleaseArea, ...] | None, BeforeValidator(parse_release)] = None
    velocity: Annotated[tuple[Expr, Expr], BeforeValidator(_velocity)] = ("0", "0")

    @model_validator(mode="after")
    def _one_state(self) -> InitialSpec:
        given = [self.depth, self.free_surface, self.release]
        if sum(v is not None for v in given) != 1:
            raise SpecError("give exactly one of depth, free_surface or release")
        return self

    def depth_fn(self) -> Expression | None:
        """Return the compiled depth expression, or ``None`` if ``free_surface`` is given."""
        return None if self.depth is None else compile_expression(self.depth, "initial.depth")

    def free_surface_fn(self) -> Expression | None:
        """Return the compiled free-surface expression, or ``None`` if ``depth`` is given."""
        if self.free_surface is None:
            return None
        return compile_expression(self.free_surface, "initial.free_surface")

    def velocity_fns(self) -> tuple[Expression, Expression]:
        """Return the compiled velocity components ``(u, v)``."""
        u, v = self.velocity
        return (
            compile_expression(u, "initial.velocity[0]"),
            compile_expression(v, "initial.velocity[1]"),
        )


class ModelSpec(StrictSpec):
    """How gravity acts on a flow over the terrain (:mod:`fem_runout.physics.slope`).

    Attributes:
        form: ``horizontal``: the seed's eq. 1 (full ``g`` on the vertical depth, friction on
            the horizontal speed); ``slope``: slope-consistent (``g cos²θ`` and the bed-normal
            acceleration, friction on the slope-normal thickness and the speed along the bed).
            Default: ``slope`` with ``terrain.dem``, else ``horizontal``.
        curvature: Add the centrifugal acceleration ``u·H·u`` of a curved bed to the normal
            stress of the friction (``slope`` form only). Default: on with the ``slope``
            form, as in com1DFA (``curvAccInFriction = 1``) and RAMMS.
        curvature_scale: Length [m] over which the bed is smoothed (Gaussian standard
            deviation) before its Hessian ``H`` is taken for ``u·H·u`` (in ``G`` and, with
            ``curvature``, in the friction; ``slope`` form only); the bed and its slope
            stay unsmoothed (:mod:`fem_runout.physics.bed_filter`). None: ``H`` of the nodal
            bed itself (its roughness down to the cells).
    """

    form: Literal["horizontal", "slope"] | None = None
    curvature: Bool | None = None
    curvature_scale: Real | None = Field(None, gt=0)


class CheckpointSpec(StrictSpec):
    """Checkpoints (``<output.dir>/checkpoints/checkpoint_<step>.h5``; docs/usage.md).

    Attributes:
        every: Interval of simulated time [s] (None: only when the run is stopped by a signal
            or its state goes bad).
        keep: Number of newest checkpoints kept.
    """

    every: Real | None = Field(None, gt=0)
    keep: int = Field(2, ge=1)


class OutputSpec(StrictSpec):
    """Where and how often to write results.

    ``dir`` and ``every`` are filled by :class:`Case` (``results/<name>``, ``end/10``).
    """

    dir: str | None = None
    every: Real | None = Field(None, gt=0)
    front_threshold: Real = Field(1e-3, gt=0)
    pictures: Bool = True
    vtk: Bool = False  # also write fields.pvd (VTK XML, readable by pyvista/VTK without ADIOS2)
    hazard: Bool = True  # hazard maps (GeoTIFF) and summary.json
    ascii: Bool = False  # hazard maps also as ESRI ASCII grids
    checkpoint: CheckpointSpec = CheckpointSpec()


#: TG2-PC's time-step bounds (``numerics.step_bound``, :meth:`fem_runout.tg2.transport.
#: Transport.stable_dt`).
STEP_BOUNDS = ("conservative", "positivity")


class NumericsSpec(StrictSpec):
    """Wet/dry threshold [m], thin-layer depth [m], FCT switch (TG2) and particles (DAMPM).

    ``thin_depth`` is the depth under which velocities are desingularised,
    ``u = 2 h q / (h² + max(h, thin_depth)²)``; None means 1e-6 × the largest initial depth.
    """

    dry_tolerance: Real = Field(1e-6, gt=0)
    thin_depth: Real | None = Field(None, gt=0)
    fct: Bool = True
    # TG2: consistent-mass correction of the corrector, gated by a smoothness sensor
    # (fem_runout/tg2/mass_correction.py); false: the seed's lumped corrector
    mass_correction: Bool = True
    active_set: Bool = True  # TG2: work on the cells near the flow only (same bits)
    # TG2: the time step's bound (fem_runout/tg2/transport.py, stable_dt): "conservative" counts
    # the advective part |β·u| of every pair; "positivity" is the depth's own bound, where those
    # parts cancel: about half the steps of a fast flow, dry fronts sharper on fine grids and
    # behind on coarse ones (docs/method.md, "The time step's bound")
    step_bound: Literal[STEP_BOUNDS] = "conservative"
    particles_per_direction: Int = Field(2, ge=1, le=8)  # DAMPM: particles per cell and axis
    flip: Real = Field(0.9, ge=0, le=1)  # DAMPM: FLIP fraction of G2P (0 = PIC, seed eq. 38)
    # DAMPM: grid-to-particle velocity transfer, FLIP/PIC blend (``flip``) or affine (APIC)
    transfer: Literal["flip", "apic"] = "flip"
    # DAMPM: a particle column is at most this many times the grid depth where it is; null: the
    # seed's eq. 42 alone (docs/dampm.md, "Depth cap")
    depth_cap: Real | None = Field(3.0, ge=1)
    # stop the run (last good state checkpointed) once a node is faster than this [m/s]:
    # free fall from 10 km gives 443 m/s, so only a numerical blow-up gets here
    max_speed: Real | None = Field(1000.0, gt=0)


_NAME = re.compile(r"^[A-Za-z0-9_-]+$")


def _name(value: Any) -> Any:
    if not isinstance(value, str) or not _NAME.match(value):
        raise SpecError(f"must use only letters, digits, '_' and '-', got {value!r}")
    return value


def _fill_output(data: dict[str, Any]) -> dict[str, Any]:
    """Fill ``output.dir`` and ``output.every`` from ``name`` and ``time.end``."""
    output = data.get("output", {})
    if not isinstance(output, dict):
        return data
    output = dict(output)
    name = data.get("name")
    if output.get("dir") is None and isinstance(name, str) and _NAME.match(name):
        output["dir"] = f"results/{name}"
    time = data.get("time")
    end = time.get("end") if isinstance(time, dict) else None
    if end == "auto":
        end = time.get("max")
    if output.get("every") is None and is_number(end) and math.isfinite(end) and end > 0:
        output["every"] = end / 10
    return {**data, "output": output}


class Case(StrictSpec):
    """A validated run-out case.

    Attributes:
        name: Case name (letters, digits, ``_`` and ``-``).
        method: A registered method (:mod:`fem_runout.methods`).
        gravity: Gravitational acceleration [m/s^2].
        domain: Rectangle, mesh and boundary.
        terrain: Elevation expression.
        initial: Initial depth or free surface, and velocity.
        material: Density, friction and rheology.
        model: Horizontal (seed) or slope-consistent form of gravity and friction.
        time: End time and step control.
        output: Output directory and frequency.
        numerics: Wet/dry tolerance and FCT switch.
        source_dir: Folder of the case file (not serialised), for relative input paths.
    """

    name: Annotated[str, BeforeValidator(_name)]
    method: Annotated[str, BeforeValidator(_method)] = Field(default_factory=default_method)
    gravity: Real = Field(9.81, gt=0)
    domain: DomainSpec
    terrain: TerrainSpec = TerrainSpec()
    initial: InitialSpec
    material: MaterialSpec = MaterialSpec()
    model: ModelSpec = ModelSpec()
    time: TimeSpec
    output: OutputSpec = OutputSpec()
    numerics: NumericsSpec = NumericsSpec()

    _source_dir: Path | None = PrivateAttr(None)

    @model_validator(mode="before")
    @classmethod
    def _defaults_from_other_keys(cls, data: Any) -> Any:
        return _fill_output(data) if isinstance(data, dict) else data

    @model_validator(mode="after")
    def _domain_needs_dem(self) -> Case:
        d = self.domain
        if self.terrain.dem is None and d.kind == "rectangle":
            if d.extent is None:
                raise SpecError("required key is missing (or give terrain.dem)", "domain.extent")
            if d.window is not None:
                raise SpecError("only used with terrain.dem", "domain.window")
            if d.cells is None and d.cell_size is None:
                raise SpecError("give exactly one of cells: [nx, ny] or cell_size: <m>", "domain")
        return self

    @model_validator(mode="after")
    def _method_meshes(self) -> Case:
        from fem_runout import methods

        if self.domain.kind != "rectangle" and not methods.get(self.method).unstructured:
            ok = ", ".join(n for n in methods.method_names() if methods.get(n).unstructured)
            raise SpecError(f"{methods.get(self.method).display} runs on the rectangle's grid "
                            f"only so far; domain.outline and domain.mesh need: {ok}", "method")
        return self

    @model_validator(mode="after")
    def _curvature_needs_slope(self) -> Case:
        if self.model.curvature and not self.slope_form:
            raise SpecError("needs model.form: slope (the default with terrain.dem)",
                            "model.curvature")
        if self.model.curvature_scale is not None and not self.slope_form:
            raise SpecError("smooths the bed's curvature of the slope-consistent form: needs "
                            "model.form: slope (the default with terrain.dem)",
                            "model.curvature_scale")
        return self

    @property
    def curvature(self) -> bool:
        """True when the friction feels the bed's curvature (default: with the slope form)."""
        if self.model.curvature is None:
            return self.slope_form
        return bool(self.model.curvature)

    @property
    def slope_form(self) -> bool:
        """True for the slope-consistent form (``model.form``, default: with a DEM)."""
        if self.model.form is None:
            return self.terrain.dem is not None
        return self.model.form == "slope"

    def __eq__(self, other: object) -> bool:
        """Equal when all fields are equal (``source_dir`` is ignored)."""
        if not isinstance(other, Case):
            return NotImplemented
        return self.__dict__ == other.__dict__

    def __hash__(self) -> int:
        return hash(tuple(self.__dict__.values()))

    @property
    def source_dir(self) -> Path | None:
        """Folder of the case file, or ``None`` if the case did not come from a file."""
        return self._source_dir

    def with_source_dir(self, source_dir: str | Path | None) -> Case:
        """Return a copy of this case whose relative input paths resolve against ``source_dir``."""
        case = self.model_copy()
        case._source_dir = None if source_dir is None else Path(source_dir).resolve()
        return case

    def resolve_input(self, path: str | Path) -> Path:
        """Resolve an input file path; relative paths are relative to the case file folder.

        Without a case file, relative paths are relative to the current working directory.
        ``${FEM_RUNOUT_DATA}`` expands to the data folder (``geo.data_folder``).
        """
        p = Path(expand_data_path(str(path))).expanduser()
        if p.is_absolute():
            return p
        return (self._source_dir or Path.cwd()) / p

    @property
    def output_dir(self) -> Path:
        """The output directory (relative paths are relative to the working directory)."""
        return Path(self.output.dir or f"results/{self.name}")

    def initial_depth(self, x: Any, y: Any) -> np.ndarray:
        """Return the initial depth: ``depth``, ``max(free_surface - elevation, 0)`` or release."""
        if self.initial.release is not None:
            from fem_runout.terrain.nodes import release_depth

            xa, ya = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
            return release_depth(self, xa.ravel(), ya.ravel()).reshape(xa.shape)
        depth = self.initial.depth_fn()
        if depth is not None:
            return depth(x, y)
        surface = self.initial.free_surface_fn()
        assert surface is not None
        return np.maximum(surface(x, y) - self.terrain.elevation_fn()(x, y), 0.0)
