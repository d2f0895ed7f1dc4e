"""Physics of the run-out model: bed friction (seed eq. 2; Manning) and rheology (eqs. 3-7)."""

from fem_runout.physics.friction import (
    Coulomb,
    FrictionLaw,
    Manning,
    Voellmy,
    friction_from_spec,
    relaxed_sign,
)
from fem_runout.physics.rheology import Bingham, rheology_from_spec

__all__ = [
    "Bingham",
    "Coulomb",
    "FrictionLaw",
    "Manning",
    "Voellmy",
    "friction_from_spec",
    "relaxed_sign",
    "rheology_from_spec",
]
