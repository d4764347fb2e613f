"""A further step on a drawn case's rig (reference/next_step.py): the same rig, causes and
measurement chain at the new drive, the drive starting at phase 0 with the pendulum at
rest, fresh noise; bad settings refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference.forced_records import (
    DriveTruth,
    ForcedCase,
    MeasurementChain,
    RigTruth,
    generate,
)
from reference.next_step import at_setting
from reference.regime_truth import RegimeTruth

RIG = RigTruth(m_kg=0.0326, l_m=0.05, L_m=0.048, R_m=0.0095, g_m_s2=9.81, zeta=0.05,
               E_Pa=2.0e6, mu0_s_per_m=0.8)
CASE = ForcedCase(
    seed=5, attempt=0, causes={"sensor_offset": {"offset_rad": 0.003}}, rig=RIG,
    drive=DriveTruth(stated_frequency_hz=10.0, frequency_hz=10.003, stated_amplitude_m=1e-3,
                     beta=1e-3 / RIG.L_m, phase_rad=1.0),
    measurement=MeasurementChain(angle_noise_rad=1e-3, angle_step_rad=math.pi / 2**16,
                                 laser=True, table_noise_m=1e-5, table_step_m=0.1 / 2**16,
                                 noise_seed=12345),
    theta0_rad=-0.1, theta_dot0_rad_s=0.5, transient_s=10.0, duration_s=60.0,
    sample_rate_hz=500.0, regime_truth=RegimeTruth("periodic", 1, None, 0.0))


def test_the_step_is_the_same_rig_at_the_new_drive_from_rest() -> None:
    step = at_setting(CASE, 2.0, 3e-3, settle_s=1.5, dwell_s=2.0)
    assert (step.rig, step.causes, step.sample_rate_hz) == (RIG, CASE.causes, 500.0)
    assert (step.theta0_rad, step.theta_dot0_rad_s) == (0.0, 0.0)
    assert (step.transient_s, step.duration_s) == (1.5, 2.0)
    assert step.drive.stated_frequency_hz == 2.0 and step.drive.stated_amplitude_m == 3e-3
    assert step.drive.frequency_hz == pytest.approx(2.0 * 1.0003)  # the same shaker's detuning
    # the drive starts at phase 0 when the settle begins
    start = float(step.table().phase(-1.5))
    assert math.remainder(start, 2.0 * math.pi) == pytest.approx(0.0, abs=1e-9)
    assert step.measurement.angle_noise_rad == CASE.measurement.angle_noise_rad
    assert step.motion is not None and step.motion.time_s.size == 1000
    record = generate(step)
    # the offset is read on the dwell: the mean reading is the offset plus the mean swing
    assert abs(np.mean(record.angle_rad - record.true_angle_rad) - 0.003) < 2e-4


def test_each_step_has_its_own_noise() -> None:
    first = at_setting(CASE, 10.0, 1e-3, 0.5, 1.0, step=1)
    second = at_setting(CASE, 10.0, 1e-3, 0.5, 1.0, step=2)
    seeds = {CASE.measurement.noise_seed, first.measurement.noise_seed,
             second.measurement.noise_seed}
    assert len(seeds) == 3
    np.testing.assert_array_equal(first.motion.theta_rad, second.motion.theta_rad)
    assert not np.array_equal(generate(first).angle_rad, generate(second).angle_rad)


@pytest.mark.parametrize(("settings", "message"), [
    ((0.0, 1e-3, 1.0, 1.0), "frequency_hz = 0.0"),
    ((2.0, -1e-3, 1.0, 1.0), "amplitude_m = -0.001"),
    ((2.0, 1e-3, -1.0, 1.0), "settle_s = -1.0"),
    ((2.0, 1e-3, 1.0, math.nan), "dwell_s = nan"),
])
def test_bad_settings_are_refused(settings, message) -> None:
    with pytest.raises(ValueError, match=message):
        at_setting(CASE, *settings)
