"""Effects outside the registry: each does to the record what it says, and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from reference.forced_records import draw_forced_case, generate
from reference.unregistered import EFFECTS, with_effect


@pytest.fixture(scope="module")
def clean():
    return draw_forced_case(41, "none", frequency_hz=10.0, laser=True, duration_s=5.0)


def _with(clean, effect: str, seed: int = 3):
    values = EFFECTS[effect].draw(np.random.default_rng(seed), clean, 1.0)
    return values, with_effect(clean, effect, values, judged=False)


def test_sensor_effects_change_the_reading_by_exactly_themselves(clean):
    base = generate(clean)
    t = base.time_s
    along = (t - t[0]) / (t[-1] - t[0])
    step = clean.measurement.angle_step_rad
    hum, case = _with(clean, "sensor_hum")
    expected = hum["amplitude_rad"] * np.sin(2 * np.pi * hum["frequency_hz"] * t
                                             + hum["phase_rad"])
    assert np.max(np.abs(generate(case).angle_rad - base.angle_rad - expected)) <= 1.01 * step
    zero, case = _with(clean, "sensor_zero_drift")
    change = generate(case).angle_rad - base.angle_rad
    assert np.max(np.abs(change - zero["offset_change_rad"] * along)) <= 1.01 * step
    gain, case = _with(clean, "sensor_gain_drift")
    change = generate(case).angle_rad - base.angle_rad
    noiseless = clean.motion.theta_rad
    assert np.max(np.abs(change - gain["gain_change"] * along * noiseless)) < 0.01 * np.max(
        np.abs(change))
    for record in (generate(case),):  # the motion and the drive channels are untouched
        np.testing.assert_array_equal(record.tach, base.tach)
        np.testing.assert_array_equal(record.table_m, base.table_m)


def test_drive_effects_move_the_tach_or_the_table(clean):
    base = generate(clean)
    delay, case = _with(clean, "tach_delay")
    pulses, moved = np.flatnonzero(base.tach), np.flatnonzero(generate(case).tach)
    shift = delay["delay_s"] * clean.sample_rate_hz
    assert np.all(np.abs(moved - pulses[: moved.size] - shift) <= 1.0)
    off, case = _with(clean, "drive_frequency_off")
    spacing = np.diff(np.flatnonzero(generate(case).tach)).mean() / clean.sample_rate_hz
    assert 1.0 / spacing == pytest.approx(clean.drive.frequency_hz * (1 + off["relative"]),
                                          rel=2e-3)
    wander, case = _with(clean, "drive_gain_wander")
    t = base.time_s
    gain = 1 + wander["depth"] * np.sin(2 * np.pi * wander["frequency_hz"] * t
                                        + wander["phase_rad"])
    np.testing.assert_allclose(case.table().displacement(t), gain * clean.table().displacement(t),
                               rtol=1e-12, atol=1e-15)
    # the table's acceleration is the second derivative of its displacement
    h = 1e-4
    for when in (0.3, 1.7, 4.2):
        x = case.table().displacement(np.array([when - h, when, when + h]))
        numeric = (x[0] - 2 * x[1] + x[2]) / h**2
        assert case.table().acceleration(when) == pytest.approx(numeric, rel=1e-4)


def test_physics_effects_move_the_pendulum_and_noise_gets_heavy_tails(clean):
    for effect in ("pivot_hairspring", "barrier_warming"):
        _, case = _with(clean, effect)
        assert case.pendulum() != clean.pendulum()
        assert np.max(np.abs(case.motion.theta_rad - clean.motion.theta_rad)) > 1e-3, effect
    _, case = _with(clean, "heavy_tailed_noise")
    noise = generate(case).angle_rad - clean.motion.theta_rad
    gaussian = generate(clean).angle_rad - clean.motion.theta_rad
    kurtosis = [np.mean(x**4) / np.mean(x**2) ** 2 for x in (noise, gaussian)]
    assert kurtosis[1] == pytest.approx(3.0, abs=0.3) and kurtosis[0] > 6.0, kurtosis
    mad = [np.median(np.abs(x)) for x in (noise, gaussian)]
    assert mad[0] == pytest.approx(mad[1], rel=0.1)
