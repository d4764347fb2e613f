"""The visibility of a drawn cause: what the baseline cannot absorb by refitting its own
parameters, and the generator handing out only causes that show."""

from __future__ import annotations

from dataclasses import replace

import pytest

from reference import forced_records, visibility
from reference.cause_sizes import CAUSES
from reference.forced_records import (
    ForcedCase,
    draw_forced_case,
    simulate_true_motion,
    visibility_of,
)
from reference.visibility import SHOWS_OVER_NOISE, cause_visibility

SHORT = {"duration_s": 3.0, "sample_rate_hz": 500.0}


@pytest.fixture(scope="module")
def clean_case() -> ForcedCase:
    return draw_forced_case(41, "none", frequency_hz=2.0, **SHORT)


def _visibility_with(case: ForcedCase, causes: dict[str, dict[str, float]]):
    """The visibility of ``causes`` put into the clean case's record."""
    caused = replace(case, causes=causes)
    return visibility_of(caused, simulate_true_motion(caused))


def test_a_cause_the_baseline_reproduces_exactly_does_not_show(clean_case):
    # Hertz's law with a 30 % stiffer barrier is the baseline itself at another K
    stiffer = clean_case.rig.K_N_per_m1_5 * 1.3
    seen = _visibility_with(clean_case, {"contact_exponent": {"n": 1.5, "K_n": stiffer}})
    assert seen.effect_over_noise > 2.0
    assert seen.visible_over_noise < 0.1
    assert not seen.shows


def test_a_gross_cause_shows_far_above_the_threshold(clean_case):
    # a zero offset of 20 noise sigmas: a window's free swing from a refitted state mimics
    # part of a constant, no refit of omega, damping or contact makes all of it
    offset = 20 * clean_case.measurement.angle_noise_rad
    seen = _visibility_with(clean_case, {"sensor_offset": {"offset_rad": offset}})
    assert seen.effect_over_noise == pytest.approx(20.0, rel=1e-6)
    assert seen.visible_over_noise > 10 * SHOWS_OVER_NOISE


@pytest.mark.parametrize("cause", CAUSES)
def test_every_drawn_cause_shows(cause):
    frequency = (2.0, 10.0)[CAUSES.index(cause) % 2]
    case = draw_forced_case(61, cause, frequency_hz=frequency, **SHORT)
    assert case.cause == cause
    assert case.visibility.shows
    assert case.visibility.visible_over_noise <= case.visibility.effect_over_noise + 1e-9


def test_the_verdict_does_not_hang_on_where_the_windows_fall():
    case = draw_forced_case(62, "coulomb_friction", frequency_hz=10.0, **SHORT)
    motion = case.motion
    again = cause_visibility(
        forced_records.true_pendulum(case.rig, {}), forced_records.true_table(case.drive, {}),
        motion.time_s, motion.theta_rad, motion.theta_dot_rad_s,
        forced_records.sensor_reading(motion, case.causes), case.measurement.angle_noise_rad,
        windows=visibility.WINDOWS - 1,
    )
    assert again.windows == case.visibility.windows - 1  # other places in the record
    assert again.visible_over_noise > 0.5 * SHOWS_OVER_NOISE


def test_a_cause_that_cannot_show_is_named(monkeypatch):
    monkeypatch.setattr(visibility, "SHOWS_OVER_NOISE", 1e6)
    monkeypatch.setattr(forced_records, "MAX_ATTEMPTS", 1)
    with pytest.raises(RuntimeError, match="sensor_lag does not show in this record at any "
                                           "plausible size"):
        draw_forced_case(63, "sensor_lag", duration_s=1.0, sample_rate_hz=500.0)


def test_bad_input_is_named(clean_case):
    motion = clean_case.motion
    args = (forced_records.true_pendulum(clean_case.rig, {}),
            forced_records.true_table(clean_case.drive, {}), motion.time_s, motion.theta_rad,
            motion.theta_dot_rad_s)
    with pytest.raises(ValueError, match="reading_rad"):
        cause_visibility(*args, motion.theta_rad[:-1], 1e-3)
    with pytest.raises(ValueError, match="noise_rad"):
        cause_visibility(*args, motion.theta_rad, 0.0)


def _stretch(case: ForcedCase, causes: dict[str, dict[str, float]], part: slice
             ) -> visibility.Stretch:
    """The clean case's record under ``causes``, cut to ``part``, as one stretch."""
    caused = replace(case, causes=causes)
    motion = simulate_true_motion(caused)
    return visibility.Stretch(forced_records.true_table(case.drive, {}), motion.time_s[part],
                              motion.theta_rad[part], motion.theta_dot_rad_s[part],
                              forced_records.sensor_reading(motion, causes)[part])


def test_stretches_share_the_refit_of_the_rig(clean_case):
    # One stiffer barrier under both halves of the record is the baseline at another K; a
    # barrier stiffer under one half and softer under the other is no rig: each half alone
    # is absorbed, the two together are not (a sweep's steps share omega, zeta, K and mu0)
    k = clean_case.rig.K_N_per_m1_5
    half = clean_case.time_s().size // 2
    first, second = slice(0, half), slice(half, None)
    stiff = {"contact_exponent": {"n": 1.5, "K_n": 2.0 * k}}
    soft = {"contact_exponent": {"n": 1.5, "K_n": 0.5 * k}}
    baseline = forced_records.true_pendulum(clean_case.rig, {})
    noise = clean_case.measurement.angle_noise_rad
    one_rig = visibility.stretches_visibility(
        baseline, [_stretch(clean_case, stiff, first), _stretch(clean_case, stiff, second)],
        noise, windows=2)
    two_rigs = [_stretch(clean_case, stiff, first), _stretch(clean_case, soft, second)]
    alone = [visibility.stretches_visibility(baseline, [s], noise, windows=2)
             for s in two_rigs]
    together = visibility.stretches_visibility(baseline, two_rigs, noise, windows=2)
    assert one_rig.windows == together.windows == 4
    assert one_rig.effect_over_noise > 2.0 and not one_rig.shows
    assert not any(a.shows for a in alone)
    assert together.shows


def test_stretches_are_required(clean_case):
    with pytest.raises(ValueError, match="stretches"):
        visibility.stretches_visibility(
            forced_records.true_pendulum(clean_case.rig, {}), [], 1e-3)
