"""The strobe clock locked to the tachometer, and the strobe points from local fits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dynamics import (
    clock_from_drive,
    clock_from_tach,
    strobe_record,
    strobe_samples,
)

FS = 1000.0
DRIVE_HZ = 7.3  # 136.99 samples per period: the pulses' quantisation changes from one to the next
PHASE_RAD = 1.1  # drive phase at sample 0: x = A sin(2 pi f t + phase)


def _crossings(n_samples: int) -> np.ndarray:
    """Exact drive-phase-0 instants [samples] of the drive within the record."""
    first = ((-PHASE_RAD / (2 * math.pi)) % 1.0) * FS / DRIVE_HZ
    return first + np.arange(0, n_samples, FS / DRIVE_HZ)[: int(n_samples * DRIVE_HZ / FS)]


def _lab_pulses(n_samples: int, seed: int) -> np.ndarray:
    """Pulses as a lab records them: on the first sample at or after the crossing (the tach
    line is sampled), give or take one, one missing, one doubled by a bounce, one spurious
    (also before the first true pulse)."""
    rng = np.random.default_rng(seed)
    crossings = _crossings(n_samples)
    pulses = np.ceil(crossings) + rng.integers(-1, 2, crossings.size)
    pulses = np.delete(pulses, 40)
    bounce = pulses[70] + 1
    spurious = [pulses[0] - 0.45 * FS / DRIVE_HZ, pulses[100] + 0.4 * FS / DRIVE_HZ]
    pulses = np.concatenate([pulses, [bounce], spurious])
    return np.sort(pulses[(pulses >= 0) & (pulses < n_samples)])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_tach_clock_keeps_time_through_missing_extra_and_jittered_pulses(seed):
    n = int(30 * FS)
    clock = clock_from_tach(_lab_pulses(n, seed), FS, stated_frequency_hz=DRIVE_HZ)
    assert clock.source == "tach"
    # 200 pulses with a sample of jitter fix the frequency to ~5e-5 Hz, and it is right
    assert clock.frequency_se_hz < 1e-4
    assert abs(clock.frequency_hz - DRIVE_HZ) < 5 * clock.frequency_se_hz
    # a sample of jitter on each pulse, averaged over 200 of them: the start within a sample
    # (the fitted start's standard error is ~0.12 sample)
    sample_rad = 2 * math.pi * DRIVE_HZ / FS
    assert abs(math.remainder(clock.phase_at_start_rad - PHASE_RAD, 2 * math.pi)) < sample_rad
    # and it knows how well it knows the time: the true instant within 5 standard errors
    true_first = _crossings(n)[0]
    assert abs(clock.first_index - true_first) < 5 * clock.timing_se_samples(true_first)
    assert clock.timing_se_samples(clock.centre_index) < clock.timing_se_samples(true_first)
    assert clock.missing_pulses == 1
    assert clock.extra_pulses == 3
    assert 0.5 < clock.jitter_rms_samples < 1.0
    assert clock.summary()["stated_frequency_hz"] == DRIVE_HZ


def test_without_a_stated_frequency_the_clock_comes_from_the_pulses_alone():
    n = int(30 * FS)
    clock = clock_from_tach(_lab_pulses(n, 4), FS)
    assert abs(clock.frequency_hz - DRIVE_HZ) < 5 * clock.frequency_se_hz
    assert clock.stated_frequency_hz is None


def test_the_stated_clock_puts_drive_phase_zero_where_the_table_crosses_upwards():
    clock = clock_from_drive(DRIVE_HZ, FS, phase_rad=PHASE_RAD)
    t = (clock.first_index + np.arange(5) * clock.period_samples) / FS
    phase = 2 * math.pi * DRIVE_HZ * t + PHASE_RAD
    assert np.allclose(np.sin(phase), 0.0, atol=1e-12)
    assert np.all(np.cos(phase) > 0)
    assert 0 <= clock.first_index < clock.period_samples
    assert clock.phase_at_start_rad == pytest.approx(PHASE_RAD)
    assert clock.timing_se_samples(np.array([0.0, 1e6])).tolist() == [0.0, 0.0]


def test_strobe_points_are_the_signal_at_the_drive_phases():
    n = int(10 * FS)
    t = np.arange(n) / FS
    w = 2 * math.pi * DRIVE_HZ

    def motion(time_s):
        return 0.1 * np.sin(w * time_s + PHASE_RAD + 0.3) + 0.03 * np.sin(0.5 * w * time_s)

    strobe = strobe_samples(motion(t), clock_from_drive(DRIVE_HZ, FS, phase_rad=PHASE_RAD))
    d = strobe.phases_per_period
    instants = strobe.time_s[:, None] + np.arange(d)[None, :] / (d * DRIVE_HZ)
    assert np.max(np.abs(strobe.points - motion(instants))) < 1e-5
    assert np.allclose(strobe.section, strobe.points[:, 0])
    assert np.all(np.diff(strobe.periods) == 1)
    assert len(strobe) == int(10 * DRIVE_HZ) - 1  # whole periods with their fit windows inside


def test_the_noise_gain_is_the_noise_of_a_strobe_point():
    """White noise through the local fits: the scatter of the points is sigma times the gain."""
    sigma = 1e-3
    noise = sigma * np.random.default_rng(5).normal(size=int(120 * FS))
    strobe = strobe_samples(noise, clock_from_drive(DRIVE_HZ, FS))
    predicted = sigma * np.sqrt(np.mean(strobe.noise_gain**2))
    assert np.std(strobe.points) == pytest.approx(predicted, rel=0.05)
    assert 0.3 < np.mean(strobe.noise_gain) < 1.0  # a fit over several samples beats one


def test_a_missing_sample_spoils_only_the_points_whose_fit_window_holds_it():
    theta = np.sin(np.arange(int(5 * FS)) / 50.0)
    clock = clock_from_drive(DRIVE_HZ, FS)
    theta[round(clock.first_index + 10 * clock.period_samples)] = np.nan
    strobe = strobe_samples(theta, clock)
    assert np.count_nonzero(np.isnan(strobe.points)) == 1
    assert np.count_nonzero(np.isnan(strobe.noise_gain)) == 0


def test_a_record_without_pulses_is_strobed_on_the_stated_drive():
    theta = np.zeros(int(5 * FS))
    strobe = strobe_record(theta, FS, tach_indices=np.zeros(0), frequency_hz=DRIVE_HZ)
    assert strobe.clock.source == "stated"
    with pytest.raises(ValueError, match="no stated drive frequency"):
        strobe_record(theta, FS, tach_indices=np.array([5, 142]))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: clock_from_tach(np.array([10.0, 147.0]), FS), "need at least 3"),
        (lambda: clock_from_tach(np.array([1.0, np.nan, 3.0]), FS), "NaN"),
        (lambda: clock_from_drive(0.0, FS), "drive frequency must be > 0"),
        (lambda: clock_from_drive(DRIVE_HZ, -1.0), "sample rate must be > 0"),
        (
            lambda: strobe_samples(np.zeros(100), clock_from_drive(DRIVE_HZ, FS)),
            "no whole drive period",
        ),
        (
            lambda: strobe_samples(
                np.zeros(5000), clock_from_drive(DRIVE_HZ, FS), window_samples=31
            ),
            "reaches past the next strobe phase",
        ),
    ],
)
def test_bad_input_is_refused_naming_what_was_wrong(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_wrong_stated_frequency_does_not_mislead_the_tach_clock():
    clock = clock_from_tach(_lab_pulses(int(30 * FS), 5), FS, stated_frequency_hz=8.0)
    assert abs(clock.frequency_hz - DRIVE_HZ) < 5 * clock.frequency_se_hz
    assert clock.summary()["stated_frequency_hz"] == 8.0


def test_every_pulse_doubled_by_a_bounce_still_gives_the_clock():
    """The spacings alternate between 1 sample and a period less one: the stated drive
    places the pulses where their spacing cannot."""
    pulses = _lab_pulses(int(30 * FS), 6)
    bounced = np.sort(np.concatenate([pulses, pulses + 1]))
    clock = clock_from_tach(bounced, FS, stated_frequency_hz=DRIVE_HZ)
    # (keeping the pulse nearer the clock of each pair shrinks the scatter the standard
    # error is made from, so the check is on the frequency itself)
    assert clock.frequency_hz == pytest.approx(DRIVE_HZ, rel=1e-4)
    assert clock.extra_pulses >= pulses.size - 3
