"""Parameter identification: free decay (L, zeta), impact decay (K, mu0, theta_b), forced records
(everything a forced record determines, and its drive)."""

from analysis.identify.drive import MeasuredDrive, fit_drive, measure_drive
from analysis.identify.forced import fit_forced, identify_forced
from analysis.identify.free_decay import (
    AVERAGING_MAX_AMPLITUDE_RAD,
    averaging_solution,
    fit_free_decay,
    pool_free_decays,
)
from analysis.identify.impact_decay import fit_impact_decay
from analysis.identify.result import (
    Estimate,
    FitQuality,
    IdentificationError,
    IdentificationResult,
)

__all__ = [
    "AVERAGING_MAX_AMPLITUDE_RAD",
    "Estimate",
    "FitQuality",
    "IdentificationError",
    "IdentificationResult",
    "MeasuredDrive",
    "averaging_solution",
    "fit_drive",
    "fit_forced",
    "fit_free_decay",
    "fit_impact_decay",
    "identify_forced",
    "measure_drive",
    "pool_free_decays",
]
