"""Drive amplitude and phase of a forced record from its table channel."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.identify import IdentificationError, fit_drive
from analysis.records import Record
from tests.tolerance import Z_999, within_999


def _forced(rng, amplitude, phase, f_true, f_stated, noise=2e-5, duration_s=5.0, fs=1000.0):
    t = np.arange(int(duration_s * fs)) / fs
    table = amplitude * np.sin(2 * math.pi * f_true * t + phase) + 3e-4
    table = table + rng.normal(0.0, noise, t.size)
    return Record(t, np.zeros(t.size), "forced", drive={"frequency_hz": f_stated},
                  table_m=table)


def test_amplitude_and_phase_within_their_intervals():
    rng = np.random.default_rng(8)
    covered = 0
    for _ in range(10):
        amplitude, phase = rng.uniform(1e-3, 8e-3), rng.uniform(-3.0, 3.0)
        result = fit_drive(_forced(rng, amplitude, phase, 7.3, 7.3))
        covered += result["amplitude_m"].contains(amplitude) and result["phase_rad"].contains(phase)
    assert covered >= 8


def test_frequency_refined_when_the_stated_one_is_off():
    rng = np.random.default_rng(9)
    amplitude, noise, n, dt = 5e-3, 2e-5, 5000, 1e-3  # _forced's record
    result = fit_drive(_forced(rng, amplitude, 0.4, 10.02, 10.0), estimate_frequency=True)
    assert within_999(result["amplitude_m"], amplitude), result["amplitude_m"]
    # the frequency reports no interval: the Cramer-Rao bound of a sine's frequency in white
    # noise (amplitude, phase and frequency unknown), widened to 99.9 %
    sigma_hz = math.sqrt(24.0) * noise / (amplitude * math.sqrt(n * (n * n - 1.0))) \
        / (2.0 * math.pi * dt)
    assert abs(result["frequency_hz"].value - 10.02) <= Z_999 * sigma_hz, result["frequency_hz"]


def test_forced_record_without_table_channel_is_refused():
    record = Record(np.arange(100) / 100.0, np.zeros(100), "forced", drive={"frequency_hz": 2.0})
    with pytest.raises(IdentificationError, match="table_m"):
        fit_drive(record)


def test_tach_pulses_at_drive_phase_zero_agree_with_the_table():
    rng = np.random.default_rng(12)
    fs, f = 1000.0, 4.0
    t = np.arange(4000) / fs
    table = 4e-3 * np.sin(2 * math.pi * f * t) + rng.normal(0.0, 2e-5, t.size)
    tach = np.flatnonzero(np.diff(np.floor(f * t), prepend=-1) > 0)  # phase 0 of each period
    agree = fit_drive(Record(t, np.zeros(t.size), "forced", drive={"frequency_hz": f},
                             table_m=table, tach_indices=tach))
    assert abs(agree.details["table_phase_at_tach_rad"]) < 0.02
    assert not agree.warnings
    shifted = fit_drive(Record(t, np.zeros(t.size), "forced", drive={"frequency_hz": f},
                               table_m=table, tach_indices=tach + 50))  # 50 ms late
    late = 2 * math.pi * f * 0.05
    assert shifted.details["table_phase_at_tach_rad"] == pytest.approx(late, abs=0.02)
    assert any("tach" in w for w in shifted.warnings)


def test_table_fit_reports_its_residual_in_metres():
    result = fit_drive(_forced(np.random.default_rng(3), 4e-3, 0.2, 5.0, 5.0, noise=2e-5))
    assert result.as_json()["quality"]["unit"] == "m"
    assert result.quality.rms_residual_rad == pytest.approx(2e-5, rel=0.1)  # the table noise
    assert " m vs noise " in result.summary()
