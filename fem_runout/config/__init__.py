"""Case files: schema, loading with overrides, and the safe expression language."""

from fem_runout.config.expr import Expression, compile_expression
from fem_runout.config.loader import dump_resolved, load_case, parse_override
from fem_runout.config.schema import (
    BoundarySides,
    Case,
    DomainSpec,
    FrictionSpec,
    InitialSpec,
    MaterialSpec,
    NumericsSpec,
    OutputSpec,
    RheologySpec,
    TerrainSpec,
    TimeSpec,
)

__all__ = [
    "BoundarySides",
    "Case",
    "DomainSpec",
    "Expression",
    "FrictionSpec",
    "InitialSpec",
    "MaterialSpec",
    "NumericsSpec",
    "OutputSpec",
    "RheologySpec",
    "TerrainSpec",
    "TimeSpec",
    "compile_expression",
    "dump_resolved",
    "load_case",
    "parse_override",
]
