"""Regime classification on sequences of known kind."""

from __future__ import annotations

import numpy as np

from analysis.dynamics import amplitude_spectrum, classify_regime

K = np.arange(600)


def test_period_one_sequence():
    rng = np.random.default_rng(1)
    points = np.column_stack(
        [0.12 + 1e-7 * rng.normal(size=K.size), -1.5 + 1e-6 * rng.normal(size=K.size)]
    )
    regime = classify_regime(points)
    assert (regime.kind, regime.period, regime.short_name) == ("periodic", 1, "period-1")


def test_period_three_sequence():
    cycle = np.array([[0.10, 1.0], [-0.05, 2.0], [0.02, -0.7]])
    points = cycle[K % 3] + 1e-6 * np.random.default_rng(2).normal(size=(K.size, 2))
    regime = classify_regime(points)
    assert (regime.kind, regime.period) == ("periodic", 3)


def test_quasi_periodic_sequence_of_two_incommensurate_frequencies():
    # stroboscopic samples of a torus: the phase advances by an irrational fraction per period
    golden = (np.sqrt(5.0) - 1.0) / 2.0
    phase = 2 * np.pi * golden * K
    points = np.column_stack([np.cos(phase), np.sin(phase)])
    regime = classify_regime(points)
    assert regime.kind == "quasi_periodic"
    assert regime.period is None
    assert regime.evidence["K"] < 0.2


def test_henon_sequence_is_chaotic(henon_orbit):
    regime = classify_regime(henon_orbit[:600])
    assert regime.kind == "chaotic"
    assert regime.evidence["K"] > 0.8
    assert regime.label.startswith("chaotic")


def test_positive_lyapunov_exponent_decides_for_chaos_even_with_few_samples(henon_orbit):
    regime = classify_regime(henon_orbit[:30], lyapunov_exponent=0.42)
    assert regime.kind == "chaotic"


def test_period_two_label_names_the_subharmonic_from_the_spectrum():
    fs, drive = 400.0, 10.0
    t = np.arange(int(30 * fs)) / fs
    theta = 0.1 * np.sin(2 * np.pi * drive * t) + 0.04 * np.sin(np.pi * drive * t + 0.3)
    theta += 0.01 * np.sin(2 * np.pi * 3 * drive * t)
    spectrum = amplitude_spectrum(theta, fs, drive_frequency_hz=drive)
    strobe = theta[:: int(fs / drive)]
    regime = classify_regime(strobe, spectrum=spectrum)
    assert regime.period == 2
    assert "1/2 f" in regime.evidence["subharmonics"]
    assert "3 f" in regime.evidence["superharmonics"]
    assert "1/2 f" in regime.label


def test_noisy_period_three_from_a_measurement_is_still_period_three():
    # 1 % sensor noise: far above the strict tolerance, so only the noise rule finds the period
    cycle = np.array([[0.10, 1.0], [-0.05, 2.0], [0.02, -0.7]])
    rng = np.random.default_rng(4)
    points = cycle[K % 3] + 0.01 * np.ptp(cycle, axis=0) * rng.normal(size=(K.size, 2))
    regime = classify_regime(points)
    assert (regime.kind, regime.period) == ("periodic", 3)
    assert classify_regime(points, noise_tolerance=0.0).kind != "periodic"


def test_noisy_period_one_from_a_measurement_is_still_period_one():
    # 1 % sensor noise on a fixed point: no lag dips below the others, yet every lag
    # returns to the same small cloud (the 0-1 test alone would read the noise as chaos)
    rng = np.random.default_rng(5)
    scale = np.array([0.2, 3.0])  # the attractor's size, e.g. from the whole trajectory
    points = np.array([0.12, -1.5]) + 0.01 * scale * rng.normal(size=(K.size, 2))
    regime = classify_regime(points, scale=scale)
    assert (regime.kind, regime.period) == ("periodic", 1)
    assert classify_regime(points, scale=scale, noise_tolerance=0.0).kind == "chaotic"


def test_noisy_chaos_is_not_mistaken_for_a_period(henon_orbit):
    rng = np.random.default_rng(6)
    noisy = henon_orbit[:600] + 0.01 * rng.normal(size=(600, 2))
    assert classify_regime(noisy).kind == "chaotic"
