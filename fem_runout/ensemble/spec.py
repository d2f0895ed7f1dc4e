"""The ensemble file: which case keys vary, how they are distributed and sampled.

Example (``cases/ensembles/avakot.yaml``)::

    members: 32
    ranks_per_member: 1
    sampling: {plan: lhs, seed: 2026}
    vary:
      material.friction.mu: {distribution: uniform, low: 0.12, high: 0.22}
      material.friction.xi: {distribution: lognormal, median: 4000, sigma: 0.4}
      initial.release.thickness: {distribution: normal, mean: 1.0, std: 0.15, low: 0.6}
    thresholds: {depth: [0.1, 0.5, 1.0], pressure: [1, 3, 30], speed: [1, 5, 10]}
    percentiles: [10, 50, 90]
    output: {dir: results/avakot_ensemble}

Every problem is one :class:`~fem_runout.errors.CaseError` naming the key path, what is wrong
and what is allowed; a varied key is also checked against the case schema with a sample value.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from fem_runout.errors import CaseError

__all__ = ["DISTRIBUTIONS", "EnsembleSpec", "Output", "Sampling", "Thresholds", "Variable",
           "load_ensemble"]

Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Variable(_Strict):
    """One varied case key: a distribution (optionally truncated to ``[low, high]``) or values.

    Attributes:
        distribution: ``uniform`` (``low``, ``high``), ``normal`` (``mean``, ``std``),
            ``lognormal`` (``median``, ``sigma`` of the logarithm) or ``values`` (a list).
        low, high: Bounds; required for uniform, optional truncation for the others.
        mean, std: Normal parameters.
        median, sigma: Log-normal parameters (``log X ~ N(log median, sigma²)``).
        values: The values of a discrete variable (``values`` distribution).
    """

    distribution: Literal["uniform", "normal", "lognormal", "values"]
    low: Finite | None = None
    high: Finite | None = None
    mean: Finite | None = None
    std: Positive | None = None
    median: Positive | None = None
    sigma: Positive | None = None
    values: tuple[Finite, ...] | None = None

    @model_validator(mode="before")
    @classmethod
    def _values_shorthand(cls, data: Any) -> Any:
        if isinstance(data, dict) and "values" in data and "distribution" not in data:
            return {"distribution": "values", **data}
        return data

    @model_validator(mode="after")
    def _parameters(self) -> Variable:
        need = {"uniform": ("low", "high"), "normal": ("mean", "std"),
                "lognormal": ("median", "sigma"), "values": ("values",)}[self.distribution]
        given = {k for k in ("low", "high", "mean", "std", "median", "sigma", "values")
                 if getattr(self, k) is not None}
        allowed = set(need) | ({"low", "high"} if self.distribution != "values" else set())
        if missing := [k for k in need if k not in given]:
            raise ValueError(f"{self.distribution} needs {', '.join(need)}; missing {missing[0]}")
        if extra := sorted(given - allowed):
            raise ValueError(f"{extra[0]} is not a parameter of {self.distribution} (allowed: "
                             f"{', '.join(sorted(allowed))})")
        if self.values is not None and not self.values:
            raise ValueError("values must list at least one number")
        if self.low is not None and self.high is not None and not self.low < self.high:
            raise ValueError(f"low must be below high, got low={self.low}, high={self.high}")
        return self

    def example(self) -> float:
        """Return a value inside the support (used to check the key on the case)."""
        if self.values is not None:
            return float(self.values[0])
        if self.low is not None and self.high is not None:
            return 0.5 * (self.low + self.high)
        centre = self.mean if self.mean is not None else self.median
        return float(min(max(centre, self.low or -math.inf), self.high or math.inf))


DISTRIBUTIONS = ("uniform", "normal", "lognormal", "values")


class Sampling(_Strict):
    """Sampling plan.

    Attributes:
        plan: ``lhs`` (Latin hypercube), ``sobol`` (scrambled Sobol points), ``random`` or
            ``factorial`` (every combination of ``values`` variables).
        seed: Seed of the plan: the same seed gives the same members.
    """

    plan: Literal["lhs", "sobol", "random", "factorial"] = "lhs"
    seed: int = Field(0, ge=0)


class Thresholds(_Strict):
    """Exceedance thresholds of the probability maps (AvaFrame's defaults for depth, pressure).

    Attributes:
        depth: Peak depth thresholds [m].
        pressure: Peak pressure thresholds [kPa].
        speed: Peak speed thresholds [m/s].
    """

    depth: tuple[Positive, ...] = (0.1, 0.5, 1.0)
    pressure: tuple[Positive, ...] = (1.0, 3.0, 30.0)
    speed: tuple[Positive, ...] = (1.0, 5.0, 10.0)


class Output(_Strict):
    """Where the ensemble writes (members under ``<dir>/members``, products in ``<dir>``)."""

    dir: Path | None = None


class EnsembleSpec(_Strict):
    """A validated ensemble file.

    Attributes:
        members: Number of members (factorial: the number of combinations, may be omitted).
        ranks_per_member: Ranks of each member's sub-communicator.
        sampling: Plan and seed.
        vary: Case key (dotted path) -> its distribution.
        thresholds: Probability-map thresholds.
        percentiles: Percentile maps of the peak depth.
        output: Output folder (default: the case's ``output.dir`` with ``_ensemble`` appended).
    """

    members: int | None = Field(None, ge=1, le=100000)
    ranks_per_member: int = Field(1, ge=1)
    sampling: Sampling = Sampling()
    vary: dict[str, Variable]
    thresholds: Thresholds = Thresholds()
    percentiles: tuple[Annotated[float, Field(gt=0, lt=100)], ...] = (10.0, 50.0, 90.0)
    output: Output = Output()

    @model_validator(mode="after")
    def _plan_fits(self) -> EnsembleSpec:
        if not self.vary:
            raise ValueError("vary must name at least one case key")
        if self.sampling.plan == "factorial":
            bad = [k for k, v in self.vary.items() if v.values is None]
            if bad:
                raise ValueError(f"sampling.plan factorial needs values lists; {bad[0]} has a "
                                 "distribution")
        elif self.members is None:
            raise ValueError(f"members is required with sampling.plan {self.sampling.plan}")
        return self


def _where(loc: tuple[Any, ...]) -> str:
    return ".".join(str(p) for p in loc if not str(p).startswith(("function-", "tagged-")))


def load_ensemble(path: str | Path, case_path: str | Path) -> EnsembleSpec:
    """Read and validate an ensemble file; check every varied key on the case.

    Args:
        path: The ensemble YAML file.
        case_path: The case file the ensemble varies.

    Raises:
        CaseError: ``<file>: <key.path>: <what is wrong>``, for the first problem found.
    """
    from fem_runout.config import load_case
    from fem_runout.config.loader import read_yaml

    label = str(path)
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise CaseError(f"ensemble file '{label}' cannot be read: {exc.strerror}") from None
    raw = read_yaml(text, label)
    if not isinstance(raw, dict):
        raise CaseError(f"{label}: must be a mapping of ensemble keys")
    try:
        spec = EnsembleSpec.model_validate(raw)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = _where(err["loc"])
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown key"
        raise CaseError(f"{label}: {where + ': ' if where else ''}{msg}") from None
    for key, variable in spec.vary.items():
        try:
            load_case(case_path, [(key, variable.example())])
        except CaseError as exc:
            raise CaseError(f"{label}: vary.{key}: not a numeric key of the case ({exc})") from None
    return spec
