"""Whether one quantity, fitted step by step, holds across a sweep: the steps' values about
their weighted mean (chi-square on their standard errors), and the weighted line through
them against the swept setting (its slope's z), for the ``constancy`` finding of
:mod:`analysis.sweep.causes`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class StepSpread:
    """The steps' scatter (chi-square, degrees of freedom, its p) and trend (slope, z)."""

    chi2: float
    dof: int
    p: float
    slope: float
    slope_z: float

    def how(self, parameter: str, z_needed: float) -> str:
        """How the quantity varies with the swept ``parameter``: a trend when the slope's z
        reaches ``z_needed``, else without one."""
        if abs(self.slope_z) >= z_needed:
            return f"{'grows' if self.slope > 0 else 'falls'} with the {parameter} " \
                   f"(slope z {self.slope_z:.3g})"
        return f"varies from step to step without a trend in the {parameter}"


def spread_across_steps(x: np.ndarray, se: np.ndarray, setting: np.ndarray) -> StepSpread:
    """The spread of values ``x`` (standard errors ``se``) at the steps' ``setting``."""
    w = np.asarray(se, dtype=float) ** -2.0
    x = np.asarray(x, dtype=float)
    setting = np.asarray(setting, dtype=float)
    chi2 = float(w @ (x - w @ x / w.sum()) ** 2)
    dof = x.size - 1
    centre = float(w @ setting / w.sum())
    spread = float(w @ (setting - centre) ** 2)
    slope = float(w @ ((setting - centre) * x)) / spread if spread > 0 else 0.0
    return StepSpread(chi2, dof, float(stats.chi2.sf(chi2, dof)), slope,
                      slope * math.sqrt(spread) if spread > 0 else 0.0)
