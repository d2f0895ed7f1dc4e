"""Sampling plans of an ensemble.

Unit-cube points (Latin hypercube, Sobol, random) are mapped through each variable's inverse
distribution function, or every combination of listed values.

The plan depends only on the ensemble file (variables in their written order, members, plan
and seed), never on the ranks, so a member's parameters are reproducible anywhere.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np

from fem_runout.ensemble.spec import EnsembleSpec, Variable

__all__ = ["inverse_cdf", "member_parameters", "unit_points"]


def unit_points(plan: str, n: int, d: int, seed: int) -> np.ndarray:
    """``(n, d)`` points in the open unit cube for ``lhs``, ``sobol`` or ``random``."""
    from scipy.stats import qmc

    if plan == "lhs":
        return qmc.LatinHypercube(d=d, rng=np.random.default_rng(seed)).random(n)
    if plan == "sobol":
        with warnings.catch_warnings():  # any n: the balance warning for n != 2^k is noise here
            warnings.simplefilter("ignore", UserWarning)
            return qmc.Sobol(d=d, scramble=True, rng=np.random.default_rng(seed)).random(n)
    if plan == "random":
        return np.random.default_rng(seed).random((n, d))
    raise ValueError(f"unknown plan {plan!r}")


def inverse_cdf(variable: Variable, u: np.ndarray) -> np.ndarray:
    """Map unit-interval values ``u`` through the variable's (truncated) inverse CDF."""
    from scipy.special import ndtr, ndtri

    u = np.clip(np.asarray(u, dtype=float), 0.0, np.nextafter(1.0, 0.0))
    if variable.distribution == "values":
        values = np.asarray(variable.values, dtype=float)
        return values[np.minimum((u * len(values)).astype(int), len(values) - 1)]
    if variable.distribution == "uniform":
        return variable.low + u * (variable.high - variable.low)
    log = variable.distribution == "lognormal"
    centre = math.log(variable.median) if log else variable.mean
    scale = variable.sigma if log else variable.std

    def z(bound: float | None, default: float) -> float:
        if bound is None:
            return default
        if log:
            return -math.inf if bound <= 0 else (math.log(bound) - centre) / scale
        return (bound - centre) / scale

    a, b = ndtr(z(variable.low, -math.inf)), ndtr(z(variable.high, math.inf))
    x = centre + scale * ndtri(a + u * (b - a))
    x = np.exp(x) if log else x
    return np.clip(x, variable.low if variable.low is not None else -np.inf,
                   variable.high if variable.high is not None else np.inf)


def member_parameters(spec: EnsembleSpec) -> list[dict[str, float]]:
    """Return every member's values of the varied keys, in member order."""
    keys = list(spec.vary)
    if spec.sampling.plan == "factorial":
        grids = [spec.vary[k].values for k in keys]
        return [{k: float(v) for k, v in zip(keys, combo, strict=True)}
                for combo in itertools.product(*grids)]
    u = unit_points(spec.sampling.plan, spec.members, len(keys), spec.sampling.seed)
    columns = [inverse_cdf(spec.vary[k], u[:, j]) for j, k in enumerate(keys)]
    return [{k: float(col[i]) for k, col in zip(keys, columns, strict=True)}
            for i in range(spec.members)]
