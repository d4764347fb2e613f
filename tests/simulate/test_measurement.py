"""The measurement model: sensor causes first, then seeded Gaussian noise, then quantization."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.measurement import MeasurementModel, has_measurement_causes
from analysis.model import Model
from analysis.packed import ParameterError


def test_noise_statistics_quantization_and_reproducibility():
    t = np.arange(200_000) / 1000.0
    theta = 0.3 * np.sin(2.0 * t)
    sensor = MeasurementModel(noise_std_rad=2e-3, quantization_rad=0.0, seed=5)
    measured = sensor.apply(t, theta)
    residual = measured - theta
    assert abs(residual.std() / 2e-3 - 1.0) < 0.01  # 200k samples: std known to ~0.2 %
    assert abs(residual.mean()) < 5 * 2e-3 / np.sqrt(t.size)
    assert np.array_equal(measured, sensor.apply(t, theta))  # same seed, same record
    assert not np.array_equal(measured, MeasurementModel(2e-3, 0.0, seed=6).apply(t, theta))
    step = 1e-3
    quantized = MeasurementModel(quantization_rad=step).apply(t, theta)
    assert np.allclose(quantized / step, np.round(quantized / step), rtol=0, atol=1e-9)
    assert np.abs(quantized - theta).max() <= step / 2 + 1e-15
    assert theta[1] == 0.3 * np.sin(2.0 * t[1])  # input untouched


def test_sensor_causes_act_before_the_noise():
    t = np.arange(1000) / 1000.0
    theta = 0.1 * np.cos(5.0 * t)
    model = Model().with_extension("sensor_offset", offset_rad=0.02)
    assert has_measurement_causes(model) and not has_measurement_causes(Model())
    ideal = MeasurementModel()
    assert ideal.is_ideal
    assert np.allclose(ideal.apply(t, theta, model), theta + 0.02, rtol=0, atol=1e-15)
    quantized = MeasurementModel(quantization_rad=0.05).apply(t, theta, model)
    assert np.allclose(quantized, np.round((theta + 0.02) / 0.05) * 0.05, rtol=0, atol=1e-15)


def test_bad_settings_are_refused():
    with pytest.raises(ParameterError, match="noise_std_rad"):
        MeasurementModel(noise_std_rad=-1.0)
    with pytest.raises(ParameterError, match="quantization_rad"):
        MeasurementModel(quantization_rad=float("nan"))
    with pytest.raises(ValueError, match="shape"):
        MeasurementModel().apply(np.arange(3.0), np.zeros(4))
