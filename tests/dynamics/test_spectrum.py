"""Amplitude spectra: line heights and harmonic labels."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from analysis.dynamics import amplitude_spectrum, harmonic_label
from analysis.dynamics.spectrum import name_ratio

FS = 500.0
DRIVE = 10.0


def _signal(components, duration_s=20.0, noise=0.0, seed=0):
    t = np.arange(int(duration_s * FS)) / FS
    x = sum(
        a * np.sin(2 * np.pi * ratio * DRIVE * t + 0.3 * k)
        for k, (ratio, a) in enumerate(components)
    )
    return x + noise * np.random.default_rng(seed).normal(size=t.size)


def test_subharmonic_fundamental_and_third_harmonic_are_labelled():
    x = _signal([(0.5, 0.2), (1.0, 1.0), (3.0, 0.05)], noise=1e-4)
    spectrum = amplitude_spectrum(x, FS, drive_frequency_hz=DRIVE)
    assert spectrum.labels[:3] == ("f", "1/2 f", "3 f")


def test_line_heights_are_the_sine_amplitudes():
    x = _signal([(1.0, 0.8), (2.0 / 3.0, 0.1)], duration_s=20.3)
    spectrum = amplitude_spectrum(x, FS, drive_frequency_hz=DRIVE)
    by_label = {peak.label: peak for peak in spectrum.peaks}
    # Hann scalloping loss is at most 1.4 dB (15 %); the parabolic refinement recovers most of it
    assert by_label["f"].amplitude == pytest.approx(0.8, rel=0.05)
    assert by_label["2/3 f"].amplitude == pytest.approx(0.1, rel=0.05)
    assert by_label["2/3 f"].harmonic == Fraction(2, 3)
    assert by_label["f"].frequency_hz == pytest.approx(DRIVE, abs=0.01)


def test_incommensurate_line_is_named_by_its_ratio():
    golden = (np.sqrt(5.0) - 1.0) / 2.0
    x = _signal([(1.0, 1.0), (golden, 0.3)], duration_s=40.0)
    spectrum = amplitude_spectrum(x, FS, drive_frequency_hz=DRIVE)
    second = spectrum.peaks[1]
    assert second.harmonic is None
    assert second.label == "0.618 f"


def test_log_scale_is_relative_to_the_largest_line():
    spectrum = amplitude_spectrum(_signal([(1.0, 2.0)]), FS, drive_frequency_hz=DRIVE)
    assert np.max(spectrum.amplitude_db) == pytest.approx(0.0)


def test_harmonic_label_text():
    assert harmonic_label(Fraction(1)) == "f"
    assert harmonic_label(Fraction(3)) == "3 f"
    assert harmonic_label(Fraction(1, 2)) == "1/2 f"
    assert harmonic_label(Fraction(2, 3)) == "2/3 f"
    assert name_ratio(5.0, 10.0, tolerance_hz=0.05) == (Fraction(1, 2), "1/2 f")


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="NaN"):
        amplitude_spectrum(np.array([0.0, np.nan] * 10), FS)
    with pytest.raises(ValueError, match="fs_hz"):
        amplitude_spectrum(np.zeros(100), 0.0)
