"""What an identification returns: estimates with 95 % intervals, fit quality, warnings."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.estimate_text import estimate_text


class Residuals:
    """rss, n and rms of a fit's ``residual`` array (model - data, NaN where not fitted)."""

    residual: np.ndarray

    @property
    def rss(self) -> float:
        """Residual sum of squares over the fitted samples [rad^2]."""
        r = self.residual[np.isfinite(self.residual)]
        return float(r @ r)

    @property
    def n(self) -> int:
        """Number of fitted samples."""
        return int(np.count_nonzero(np.isfinite(self.residual)))

    @property
    def rms(self) -> float:
        """RMS residual over the fitted samples [rad]."""
        return math.sqrt(self.rss / max(self.n, 1))


class SampledRecord:
    """Sample period and usable-sample count of a record's uniform times ``t`` and its
    ``valid`` mask (the fits' views of a record share them)."""

    t: np.ndarray
    valid: np.ndarray

    @property
    def dt(self) -> float:
        """Sample period [s]."""
        return float(self.t[1] - self.t[0])

    @property
    def n_valid(self) -> int:
        """Number of usable samples."""
        return int(np.count_nonzero(self.valid))


class IdentificationError(ValueError):
    """A record cannot be fitted; the message says why (too short, no oscillation, ...)."""


@dataclass(frozen=True)
class Estimate:
    """One identified value with its 95 % confidence interval (None when not known)."""

    value: float
    ci95: tuple[float, float] | None = None

    @property
    def half_width(self) -> float:
        """Half the interval width (nan without an interval)."""
        if self.ci95 is None:
            return math.nan
        return 0.5 * (self.ci95[1] - self.ci95[0])

    def contains(self, value: float) -> bool:
        """True when ``value`` lies inside the interval."""
        return self.ci95 is not None and self.ci95[0] <= value <= self.ci95[1]

    def as_json(self) -> dict[str, Any]:
        """``{"value": v, "ci95": [lo, hi]}`` (docs/MODEL.md section 7); ci95 omitted when
        unknown."""
        out: dict[str, Any] = {"value": float(self.value)}
        if self.ci95 is not None:
            out["ci95"] = [float(self.ci95[0]), float(self.ci95[1])]
        return out


@dataclass(frozen=True)
class FitQuality:
    """How well the model explains the samples used.

    ``noise_rad`` is the sample-to-sample noise seen in the data alone; a residual
    RMS far above it means structure the model does not explain.
    ``variance_inflation`` is the factor by which correlated residuals widen the
    intervals over the white-noise formula (1 for white residuals).
    """

    rms_residual_rad: float
    noise_rad: float
    n_samples: int
    n_excluded: int
    variance_inflation: float
    residual_lag1_correlation: float
    unit: str = "rad"  # of the residual and noise: "m" for a fit of the table channel

    def as_json(self) -> dict[str, Any]:
        """Plain dict for JSON (residual and noise in ``unit`` despite the keys' '_rad')."""
        return {
            "unit": self.unit,
            "rms_residual_rad": self.rms_residual_rad,
            "noise_rad": self.noise_rad,
            "n_samples": self.n_samples,
            "n_excluded": self.n_excluded,
            "variance_inflation": self.variance_inflation,
            "residual_lag1_correlation": self.residual_lag1_correlation,
        }


@dataclass(frozen=True)
class IdentificationResult:
    """Identified parameters of one experiment (docs/MODEL.md section 7 keys) and how they were
    found."""

    experiment: str
    method: str
    parameters: dict[str, Estimate]
    quality: FitQuality
    warnings: tuple[str, ...] = ()
    details: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, key: str) -> Estimate:
        return self.parameters[key]

    def as_json(self) -> dict[str, Any]:
        """The JSON report of ``impact-rig identify``."""
        return {
            "experiment": self.experiment,
            "method": self.method,
            "parameters": {key: est.as_json() for key, est in self.parameters.items()},
            "quality": self.quality.as_json(),
            "warnings": list(self.warnings),
            "details": self.details,
        }

    def summary(self) -> str:
        """Readable multi-line summary: values with intervals, fit quality, warnings."""
        lines = [f"experiment: {self.experiment}   method: {self.method}"]
        width = max((len(k) for k in self.parameters), default=0)
        for key, est in self.parameters.items():
            lines.append(f"  {key:<{width}}  {estimate_text(est.value, est.ci95)}")
        q = self.quality
        lines.append(
            f"fit: rms residual {q.rms_residual_rad:.3g} {q.unit} vs noise {q.noise_rad:.3g} "
            f"{q.unit}, "
            f"{q.n_samples} samples used, {q.n_excluded} excluded, interval inflation "
            f"x{math.sqrt(q.variance_inflation):.3g} for correlated residuals "
            f"(lag-1 correlation {q.residual_lag1_correlation:.3f})"
        )
        for key, value in self.details.items():
            if isinstance(value, int | float | str):
                lines.append(f"  {key}: {value}")
        lines.extend(f"warning: {w}" for w in self.warnings)
        return "\n".join(lines)
