"""Ensembles of a case: members sampled from distributions of its keys.

Members run over MPI sub-communicators and are combined into probability, percentile and
sensitivity products (docs/ensembles.md).
"""

from fem_runout.ensemble.driver import EnsembleResult, run_ensemble
from fem_runout.ensemble.spec import EnsembleSpec, load_ensemble

__all__ = ["EnsembleResult", "EnsembleSpec", "load_ensemble", "run_ensemble"]
