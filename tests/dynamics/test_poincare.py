"""Poincare sections from tachometer pulses and from the drive phase."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.dynamics import delayed_map, poincare_from_phase, poincare_from_pulses

FS = 1000.0
DRIVE = 10.0


def _period_two_motion(t):
    """Analytic response with a period-2 component: known theta and theta' at every instant."""
    w = 2 * np.pi * DRIVE
    theta = 0.1 * np.sin(w * t + 0.4) + 0.05 * np.sin(0.5 * w * t + 1.0)
    theta_dot = 0.1 * w * np.cos(w * t + 0.4) + 0.025 * w * np.cos(0.5 * w * t + 1.0)
    return theta, theta_dot


def test_pulse_section_recovers_angle_and_rate_at_the_pulses():
    t = np.arange(int(5 * FS)) / FS
    theta, _ = _period_two_motion(t)
    noisy = theta + 2e-5 * np.random.default_rng(2).normal(size=t.size)
    # pulses at Omega t = 2 pi k, not on a sample: 100.0 samples per period, offset 0.37 sample
    pulses = 0.37 + np.arange(1, 49) * FS / DRIVE
    section = poincare_from_pulses(noisy, FS, pulses)
    expected_theta, expected_rate = _period_two_motion(pulses / FS)
    assert np.allclose(section.theta, expected_theta, atol=1e-4)
    assert np.allclose(section.theta_dot, expected_rate, atol=0.02 * np.ptp(expected_rate) + 0.05)
    assert np.allclose(section.time_s, pulses / FS)


def test_phase_section_alternates_between_two_points_for_period_two():
    t = np.arange(int(5 * FS)) / FS
    theta, theta_dot = _period_two_motion(t)
    section = poincare_from_phase(t, theta, DRIVE, theta_dot=theta_dot)
    assert np.allclose(section.time_s[:3], [0.0, 0.1, 0.2])
    assert np.allclose(section.theta[2:], section.theta[:-2], atol=1e-6)
    assert not np.allclose(section.theta[1:], section.theta[:-1], atol=1e-3)


def test_phase_offset_moves_the_section():
    t = np.arange(int(2 * FS)) / FS
    theta, theta_dot = _period_two_motion(t)
    section = poincare_from_phase(t, theta, DRIVE, theta_dot=theta_dot, phase_rad=np.pi / 2)
    assert section.time_s[0] == pytest.approx(0.025)
    assert np.allclose(section.theta, _period_two_motion(section.time_s)[0], atol=1e-6)


def test_delayed_map_pairs_successive_samples():
    x_k, x_next = delayed_map(np.array([1.0, 2.0, 3.0, 4.0]))
    assert np.array_equal(x_k, [1.0, 2.0, 3.0])
    assert np.array_equal(x_next, [2.0, 3.0, 4.0])


def test_pulses_outside_the_record_are_refused():
    with pytest.raises(ValueError, match="record"):
        poincare_from_pulses(np.zeros(100), FS, np.array([10.0, 120.0]))
