"""How a simulated angle becomes a measured one: sensor causes, Gaussian noise, quantization.

The measurement causes of docs/MODEL.md section 6 (offset, nonlinearity, lag) act first,
through :func:`analysis.extensions.apply_measurement`; then white Gaussian noise of
a given standard deviation is added and the result is rounded to the converter's
step.  The random generator is seeded, so a simulated record can be reproduced.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.extensions import apply_measurement, cause
from analysis.model import Model
from analysis.packed import ParameterError


@dataclass(frozen=True)
class MeasurementModel:
    """Noise standard deviation [rad], quantization step [rad] (0: none) and the noise seed."""

    noise_std_rad: float = 0.0
    quantization_rad: float = 0.0
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("noise_std_rad", "quantization_rad"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} = {value!r}: expected a finite number >= 0")

    @property
    def is_ideal(self) -> bool:
        """True when neither noise nor quantization is applied."""
        return self.noise_std_rad == 0.0 and self.quantization_rad == 0.0

    def apply(self, t: np.ndarray, theta: np.ndarray, model: Model | None = None) -> np.ndarray:
        """The angle the sensor reports for the true angle ``theta`` sampled at ``t``.

        ``model`` supplies the measurement causes (sensor offset, nonlinearity, lag);
        without it only noise and quantization act.  The input is not modified.
        """
        t = np.asarray(t, dtype=float)
        theta = np.asarray(theta, dtype=float)
        if t.shape != theta.shape:
            raise ValueError(f"t has shape {t.shape} but theta has shape {theta.shape}")
        measured = apply_measurement(model, t, theta) if model is not None else theta.copy()
        if self.noise_std_rad > 0.0:
            rng = np.random.default_rng(self.seed)
            measured = measured + rng.normal(0.0, self.noise_std_rad, size=measured.shape)
        if self.quantization_rad > 0.0:
            measured = np.round(measured / self.quantization_rad) * self.quantization_rad
        return measured


def has_measurement_causes(model: Model) -> bool:
    """True when one of the model's active causes acts on the measurement."""
    return any(cause(name).acts_on == "measurement" for name in model.extensions)
