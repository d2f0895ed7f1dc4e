"""Time integrators: the IMEX Runge-Kutta-Chebyshev scheme of seed eqs. 17-19."""

from fem_runout.integrators.rkc import (
    IMEXRKC,
    RKCCoefficients,
    rkc_coefficients,
    spectral_radius_power,
    stability_polynomial,
    stages,
)

__all__ = [
    "IMEXRKC",
    "RKCCoefficients",
    "rkc_coefficients",
    "spectral_radius_power",
    "stability_polynomial",
    "stages",
]
