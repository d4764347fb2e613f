"""Reading a fit's residual: white noise passes for any seed, and each planted effect (a
line, a drift, heavy tails, a drive clock or a tach out of step) is named with its numbers,
found from the data alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.discrepancy.residual_reading import (
    FALSE_ALARM,
    MIN_STRUCTURE,
    backbone_finding,
    drive_frequency_finding,
    read_residual,
    timing_finding,
)
from analysis.dynamics.strobe import clock_from_tach
from analysis.identify.preprocess import noise_and_quantum
from tests.tolerance import Z_999

FS_HZ = 1000.0
DRIVE_HZ = 10.0


def _record(seed: int, *, duration_s: float = 30.0, fs_hz: float = FS_HZ, gaps: float = 0.0,
            step_rad: float | None = None, noise: str = "gauss"):
    """A forced response, its noisy (optionally quantised) reading with missing samples, and
    the residual model - data of a model that is exactly right; noise_rad is what the
    record's own noise estimate says, off by up to 10 % as the caller's may be."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * fs_hz)) / fs_hz
    sigma = rng.uniform(2e-4, 1e-3)
    phase = rng.uniform(0, 2 * np.pi)
    model = (0.3 * np.sin(2 * np.pi * DRIVE_HZ * t + phase)
             + 0.04 * np.sin(2 * np.pi * 3 * DRIVE_HZ * t + 2 * phase))
    if noise == "gauss":
        error = rng.normal(0.0, sigma, t.size)
    else:
        error = sigma * rng.standard_t(3, t.size)
    data = model + error
    if step_rad is not None:
        data = np.round(data / step_rad) * step_rad
    valid = rng.random(t.size) >= gaps
    data = np.where(valid, data, np.nan)
    noise_rad = noise_and_quantum(data)[0] * rng.uniform(0.9, 1.1)
    return t, model - data, valid, noise_rad, model, rng


CLEAN = [
    {"gaps": 0.0},
    {"gaps": 0.03, "step_rad": math.pi / 2**16},  # 16-bit converter over +-pi/2
    # a coarse converter, steps about the noise's size: the record's noise reads low
    {"gaps": 0.02, "step_rad": 4e-4},
    {"gaps": 0.03, "fs_hz": 200.0, "duration_s": 60.0},
]


@pytest.mark.parametrize("condition", CLEAN, ids=["white", "16-bit+gaps", "coarse+gaps", "200Hz"])
def test_a_right_model_leaves_white_noise_for_any_seed(condition):
    for seed in range(8):
        t, residual, valid, noise_rad, model, _ = _record(1000 + seed, **condition)
        reading = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ,
                                model_rad=model)
        assert not reading.structured, (seed, reading.why)
        assert reading.findings == (), (seed, [f.sentence for f in reading.findings])
        assert "white noise" in reading.why
        assert reading.structured_rms_rad < MIN_STRUCTURE * reading.floor_rad


def test_a_line_off_the_drive_harmonics_is_found_with_its_frequency_and_amplitude():
    for seed in range(4):
        t, residual, valid, noise_rad, _, rng = _record(2000 + seed, gaps=0.03,
                                                        step_rad=math.pi / 2**16)
        frequency = rng.uniform(1.0, 200.0)
        while abs(frequency / DRIVE_HZ - round(frequency / DRIVE_HZ)) * DRIVE_HZ < 0.5:
            frequency = rng.uniform(1.0, 200.0)
        amplitude = rng.uniform(0.6, 3.0) * noise_rad
        residual = residual + amplitude * np.sin(2 * np.pi * frequency * t + rng.uniform(0, 6))
        # a model that also misses the drive's own harmonics: those are never lines
        residual += 2 * noise_rad * np.sin(2 * np.pi * DRIVE_HZ * t) \
            + noise_rad * np.cos(2 * np.pi * 2 * DRIVE_HZ * t)
        reading = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ)
        lines = [f for f in reading.findings if f.kind == "line"]
        assert reading.structured
        assert len(lines) == 1, [f.sentence for f in reading.findings]
        found = lines[0].numbers
        assert found["frequency_hz"] == pytest.approx(frequency, abs=0.1 / t[-1])
        assert found["amplitude_rad"] == pytest.approx(amplitude, rel=0.05)
        assert found["drive_frequency_hz"] == DRIVE_HZ
        assert f"{found['frequency_hz']:.4g} Hz" in lines[0].sentence
        assert "not a drive harmonic" in lines[0].sentence


def test_a_period_two_response_misfit_is_structure_but_no_line():
    t, residual, valid, noise_rad, _, _ = _record(3000, gaps=0.02)
    for k, size in ((1, 1.0), (3, 0.7), (5, 0.5)):  # odd multiples of half the drive's
        residual = residual + size * noise_rad * np.sin(np.pi * k * DRIVE_HZ * t + k)
    reading = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ,
                            subharmonic=2)
    assert reading.structured and reading.ljung_box_p < FALSE_ALARM
    assert reading.findings == ()
    # without being told the response's period, the half-frequency lines are lines
    told_nothing = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ)
    assert sorted(round(f.numbers["frequency_hz"], 1) for f in told_nothing.findings) == \
        [5.0, 15.0, 25.0]


def test_a_large_misfit_at_the_impacts_leaks_no_line_through_held_out_gaps():
    t, residual, valid, noise_rad, model, _ = _record(3100, duration_s=60.0, gaps=0.02)
    # the fit leaves the last quarter of every 10 s out (a held-out stretch)
    fitted = valid & (t % 10.0 < 7.5)
    kicks = 40 * noise_rad * np.exp(-((t * DRIVE_HZ) % 1.0 - 0.25) ** 2 / 2e-4)
    reading = read_residual(t, np.where(fitted, residual + kicks, np.nan), fitted, noise_rad,
                            drive_frequency_hz=DRIVE_HZ, model_rad=model)
    assert reading.structured
    # spikes locked to the drive's phase are a misfit, not heavy-tailed noise
    assert reading.findings == (), [f.sentence for f in reading.findings]


def _slope_within_999(numbers: dict, key: str, truth: float) -> bool:
    """A trend's slope within 3.29 of its standard errors of the truth: the finding reports
    the slope in standard errors (``z``, from the sandwich covariance)."""
    standard_error = abs(numbers[key]) / numbers["z"]
    return abs(numbers[key] - truth) <= Z_999 * standard_error


def test_an_offset_drift_is_a_trend_with_its_slope():
    for seed in range(3):
        t, residual, valid, noise_rad, model, rng = _record(4000 + seed, gaps=0.03)
        slope = rng.choice([-1, 1]) * rng.uniform(1.5, 4.0) * noise_rad  # rad per minute
        data_drift = slope * (t - t.mean()) / 60.0
        reading = read_residual(t, residual - data_drift, valid, noise_rad, model_rad=model)
        trends = [f for f in reading.findings if f.kind == "trend"]
        assert reading.structured
        assert len(trends) == 1 and "offset" in trends[0].sentence
        assert trends[0].numbers["z"] > 10
        assert _slope_within_999(trends[0].numbers, "offset_slope_rad_per_min", slope)


def test_a_gain_drift_is_a_trend_in_proportion_to_the_motion():
    t, residual, valid, noise_rad, model, _ = _record(4100, gaps=0.02)
    gain = -0.01  # per minute: the record's swing shrinks against the model's
    data = model - residual
    drifted = data * (1.0 + gain * (t - t.mean()) / 60.0)
    reading = read_residual(t, model - drifted, valid, noise_rad, model_rad=model)
    trends = [f for f in reading.findings if f.kind == "trend"]
    assert reading.structured
    assert [("gain" in f.sentence) for f in trends] == [True]
    assert _slope_within_999(trends[0].numbers, "gain_slope_per_min", gain)


def test_heavy_tailed_noise_is_outliers_not_structure():
    for seed in range(4):
        t, residual, valid, noise_rad, model, _ = _record(5000 + seed, noise="t3", gaps=0.02)
        reading = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ,
                                model_rad=model)
        assert not reading.structured, reading.why
        assert [f.kind for f in reading.findings] == ["outliers"]
        numbers = reading.findings[0].numbers
        # Student t with 3 degrees of freedom beyond 5 robust sigma: ~0.6 % of samples
        assert 0.002 < numbers["fraction_beyond_5_sigma"] < 0.02
        assert numbers["fraction_beyond_5_sigma"] > 1000 * numbers["gaussian_fraction"]


def test_white_residual_well_above_the_record_noise_is_structure():
    t, residual, valid, noise_rad, _, rng = _record(6000, gaps=0.02)
    louder = residual + rng.normal(0.0, 2.5 * noise_rad, t.size)
    reading = read_residual(t, louder, valid, noise_rad)
    assert reading.structured and reading.scatter_ratio > 2.4
    assert "scatter" in reading.why


def test_reading_as_json_names_every_finding():
    t, residual, valid, noise_rad, _, _ = _record(6100, gaps=0.01)
    residual = residual + 3 * noise_rad * np.sin(2 * np.pi * 7.31 * t)
    out = read_residual(t, residual, valid, noise_rad, drive_frequency_hz=DRIVE_HZ).as_json()
    assert out["structured"] is True
    assert out["findings"][0]["kind"] == "line"
    assert out["findings"][0]["frequency_hz"] == pytest.approx(7.31, abs=0.01)
    assert "7.31 Hz" in out["findings"][0]["text"]


def test_bad_inputs_are_refused_with_what_was_wrong():
    t = np.arange(1000) / FS_HZ
    with pytest.raises(ValueError, match="one length"):
        read_residual(t, np.zeros(999), None, 1e-3)
    with pytest.raises(ValueError, match="noise_rad"):
        read_residual(t, np.zeros(1000), None, 0.0)
    with pytest.raises(ValueError, match="uniformly"):
        read_residual(t**2, np.zeros(1000), None, 1e-3)


# --- the drive's channels --------------------------------------------------------------


def _drive(seed: int, *, offset_ppm: float = 0.0, tach_late_s: float = 0.0,
           duration_s: float = 60.0):
    """Table channel and tach line of a drive at DRIVE_HZ (1 + offset_ppm 1e-6), the tach
    marking phase 0 on the first sample at or after it (late by tach_late_s)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * FS_HZ)) / FS_HZ
    frequency = DRIVE_HZ * (1.0 + 1e-6 * offset_ppm)
    phase = rng.uniform(-np.pi, np.pi)
    amplitude = rng.uniform(2e-3, 6e-3)
    table = amplitude * np.sin(2 * np.pi * frequency * t + phase) \
        + 0.03 * amplitude * np.sin(2 * (2 * np.pi * frequency * t + phase) + 1.0) \
        + rng.normal(0.0, 1e-5, t.size)
    table = np.round(table / 3e-6) * 3e-6
    cycles = np.arange(math.ceil(phase / (2 * np.pi)),
                       math.floor((2 * np.pi * frequency * t[-1] + phase) / (2 * np.pi)) + 1)
    instants = (2 * np.pi * cycles - phase) / (2 * np.pi * frequency) + tach_late_s
    pulses = np.searchsorted(t, instants[(instants >= 0) & (instants <= t[-1])], side="left")
    return t, table, pulses, rng


def test_a_tach_at_the_stated_frequency_never_gives_a_drive_frequency_finding():
    for seed in range(20):
        _, _, pulses, rng = _drive(7000 + seed, offset_ppm=rng_ppm(seed))
        pulses = np.delete(pulses, rng.integers(0, pulses.size, 3))  # three pulses lost
        clock = clock_from_tach(pulses, FS_HZ, stated_frequency_hz=DRIVE_HZ)
        assert drive_frequency_finding(clock, DRIVE_HZ) is None


def rng_ppm(seed: int) -> float:
    """A drive within a few ppm of its setting, as quartz clocks keep it."""
    return float(np.random.default_rng(seed).uniform(-5.0, 5.0))


@pytest.mark.parametrize("offset_ppm", [300.0, -300.0])
def test_a_drive_300_ppm_off_its_stated_frequency_is_found_with_both_values(offset_ppm):
    for seed in range(3):
        _, _, pulses, _ = _drive(7100 + seed, offset_ppm=offset_ppm)
        finding = drive_frequency_finding(clock_from_tach(pulses, FS_HZ), DRIVE_HZ)
        assert finding is not None and finding.kind == "drive_frequency"
        numbers = finding.numbers
        assert numbers["stated_frequency_hz"] == DRIVE_HZ
        assert numbers["measured_frequency_hz"] == pytest.approx(
            DRIVE_HZ * (1 + 1e-6 * offset_ppm), rel=3e-5)
        assert numbers["offset_ppm"] == pytest.approx(offset_ppm, abs=30.0)
        assert f"{numbers['measured_frequency_hz']:.7g} Hz" in finding.sentence


def test_a_tach_in_step_with_the_table_gives_no_timing_finding():
    for seed in range(8):
        t, table, pulses, _ = _drive(8000 + seed, offset_ppm=rng_ppm(seed), duration_s=30.0)
        clock = clock_from_tach(pulses, FS_HZ, stated_frequency_hz=DRIVE_HZ)
        assert timing_finding(t, table, clock) is None


def test_a_tach_two_milliseconds_late_is_a_timing_finding_with_its_delay():
    for seed in range(3):
        t, table, pulses, _ = _drive(8100 + seed, tach_late_s=0.002)
        finding = timing_finding(t, table, clock_from_tach(pulses, FS_HZ))
        assert finding is not None and finding.kind == "timing"
        # the marks are quantised to the 1 ms sample: within half a sample of the truth
        assert finding.numbers["delay_s"] == pytest.approx(0.002, abs=0.5e-3)
        assert finding.numbers["phase_gap_rad"] == pytest.approx(
            2 * np.pi * DRIVE_HZ * finding.numbers["delay_s"])


# --- a decay's backbone ----------------------------------------------------------------


def _decay(seed: int, kappa: float, *, amplitude_rad: float = 0.35, duration_s: float = 40.0):
    """A pendulum's decay whose frequency rises as the swing shrinks, by kappa A^2 / 16
    (kappa = 1 for a pendulum), in closed form: amplitude A0 e^(-zeta w t), phase the
    integral of w (1 - kappa A^2 / 16)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * FS_HZ)) / FS_HZ
    omega, zeta = rng.uniform(12.0, 16.0), rng.uniform(0.003, 0.006)
    envelope = amplitude_rad * np.exp(-zeta * omega * t)
    phase = omega * t - kappa * amplitude_rad**2 / (32 * zeta) * (1 - np.exp(-2 * zeta * omega * t))
    return t, 0.01 + envelope * np.cos(phase + rng.uniform(0, 2 * np.pi)), rng


def _noisy(curve: np.ndarray, rng: np.random.Generator, noise_rad: float):
    valid = rng.random(curve.size) >= 0.02
    return np.where(valid, curve + rng.normal(0.0, noise_rad, curve.size), np.nan), valid


def test_a_decay_with_the_models_backbone_gives_no_backbone_finding():
    for seed in range(6):
        t, model, rng = _decay(9000 + seed, 1.0)
        angle, valid = _noisy(model, rng, 5e-4)
        assert backbone_finding(t, angle, model, valid, 5e-4) is None


def test_a_decay_stiffening_faster_than_the_model_is_a_backbone_finding():
    for seed, kappa in ((9100, 1.3), (9101, 0.6)):
        t, model, rng = _decay(seed, 1.0)
        _, truth, _ = _decay(seed, kappa)
        angle, valid = _noisy(truth, rng, 5e-4)
        finding = backbone_finding(t, angle, model, valid, 5e-4)
        assert finding is not None and finding.kind == "backbone"
        n = finding.numbers
        span = (n["amplitude_high_rad"] ** 2 - n["amplitude_low_rad"] ** 2) / 16.0
        # the frequency rises by kappa (A_high^2 - A_low^2) / 16 as the swing decays
        assert n["model_frequency_change"] == pytest.approx(span, rel=0.03)
        assert n["record_frequency_change"] == pytest.approx(kappa * span, rel=0.05)
        assert n["mismatch"] == pytest.approx((kappa - 1.0) * span, rel=0.15)
