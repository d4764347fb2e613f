"""Spectral lines off the drive's harmonics: a cap on how many are fitted keeps the largest,
and the sines' least squares (normal equations) equal an orthogonal solve despite gaps."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.dynamics.lines import find_lines, fit_sines

FS_HZ = 500.0
DRIVE_HZ = 2.0


def _many_lines(seed: int):
    """60 s of 40 lines off the drive's harmonics (amplitudes 1 to 40 noise sigmas, drawn
    frequencies), white noise, and 2 % of the samples lost in short gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(60 * FS_HZ)) / FS_HZ
    frequencies = []
    while len(frequencies) < 40:
        f = rng.uniform(3.0, 200.0)
        off_harmonic = abs(f / DRIVE_HZ - round(f / DRIVE_HZ)) * DRIVE_HZ > 0.3
        if off_harmonic and all(abs(f - g) > 0.5 for g in frequencies):
            frequencies.append(f)
    amplitudes = rng.permutation(np.arange(1, 41)) * 1e-3
    x = sum(a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f, a in zip(frequencies, amplitudes, strict=True))
    x = x + rng.normal(0.0, 1e-3, t.size)
    ok = np.ones(t.size, dtype=bool)
    for start in rng.integers(0, t.size - 30, 20):
        ok[start:start + 30] = False
    return t, x, ok, np.array(frequencies), amplitudes


@pytest.mark.parametrize("seed", [1, 2])
def test_a_cap_on_the_lines_fitted_keeps_the_largest(seed):
    t, x, ok, frequencies, amplitudes = _many_lines(seed)
    found = find_lines(t, np.where(ok, x, 0.0), ok, DRIVE_HZ, max_lines=8)
    assert len(found) == 8
    # the strongest peaks are kept; the window's scalloping (under 1 dB) may swap lines
    # whose sizes differ by less than that, so a kept line is at least 0.9 of the 8th largest
    eighth = np.sort(amplitudes)[-8]
    for frequency, amplitude in found:
        k = int(np.argmin(np.abs(frequencies - frequency)))
        assert abs(frequencies[k] - frequency) < 2 * FS_HZ / t.size, frequency
        assert amplitudes[k] >= 0.9 * eighth, (frequency, amplitudes[k])
        # the largest lines, fitted beside each other only, leave the others as noise
        assert amplitude == pytest.approx(amplitudes[k], rel=0.1)


def test_sines_by_the_normal_equations_equal_an_orthogonal_solve():
    t, x, ok, frequencies, _ = _many_lines(3)
    curve, amplitudes = fit_sines(t, x, ok, list(frequencies))
    tt = t - t[0]
    basis = np.column_stack([np.ones_like(tt)] + [
        g(2 * np.pi * f * tt) for f in frequencies for g in (np.sin, np.cos)])
    coef = np.linalg.lstsq(basis[ok], x[ok], rcond=None)[0]
    # to a millionth of the noise (1e-3)
    np.testing.assert_allclose(curve, basis @ coef, rtol=0, atol=1e-9)
    np.testing.assert_allclose(amplitudes, np.hypot(coef[1::2], coef[2::2]), atol=1e-9)
