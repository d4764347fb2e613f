"""Statistics of a forced record that a chaotic response keeps even though its trajectory
cannot be predicted point by point: the distribution of the Poincare section (angle at
drive phase 0), the distribution of the swing's upper turning points (where impacts
stop it) and the power at the drive's harmonics and subharmonics.

Two records (or a record and a simulation) are compared by the Kolmogorov-Smirnov
distance of the two distributions and the mean absolute difference of the spectral
lines in decibels; a model whose invariants lie closer to the data's explains it better.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import welch
from scipy.stats import ks_2samp

LINES_PER_HARMONIC = 6  # multiples of f/6 cover period 2 and 3 subharmonics
MAX_HARMONIC = 5


@dataclass(frozen=True)
class Invariants:
    """Invariant statistics of one forced run."""

    poincare_rad: np.ndarray
    turning_points_rad: np.ndarray
    line_power_db: np.ndarray  # power at k f / 6, k = 1 .. 6 * MAX_HARMONIC


def invariants(
    t: np.ndarray, theta: np.ndarray, frequency_hz: float, phase0_rad: float = 0.0
) -> Invariants:
    """Invariants of a uniformly sampled angle under a drive x_t = A sin(2 pi f t + phase0)."""
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    good = np.isfinite(theta)
    idx = np.arange(theta.size)
    filled = np.interp(idx, idx[good], theta[good])
    period = 1.0 / frequency_hz
    first = (-phase0_rad / (2 * math.pi)) % 1.0 * period
    times = np.arange(first, t[-1], period)
    poincare = np.interp(times, t, filled)
    inner = filled[1:-1]
    turning = inner[(inner > filled[:-2]) & (inner >= filled[2:])]
    fs = 1.0 / float(t[1] - t[0])
    nper = min(filled.size, round(8 * fs * period))
    freqs, power = welch(filled - filled.mean(), fs=fs, nperseg=max(nper, 16))
    lines = frequency_hz * np.arange(1, LINES_PER_HARMONIC * MAX_HARMONIC + 1) / LINES_PER_HARMONIC
    lines = lines[lines < 0.5 * fs]
    line_power = np.interp(lines, freqs, power)
    total = float(np.sum(power)) or 1.0
    return Invariants(poincare, turning, 10.0 * np.log10(line_power / total + 1e-12))


def invariant_distance(a: Invariants, b: Invariants) -> float:
    """KS distances of the Poincare and turning-point distributions plus the mean spectral-line
    difference (in units of 20 dB): 0 for identical statistics."""
    parts = []
    for x, y in ((a.poincare_rad, b.poincare_rad), (a.turning_points_rad, b.turning_points_rad)):
        if x.size >= 5 and y.size >= 5:
            parts.append(float(ks_2samp(x, y).statistic))
    n = min(a.line_power_db.size, b.line_power_db.size)
    if n:
        parts.append(float(np.mean(np.abs(a.line_power_db[:n] - b.line_power_db[:n]))) / 20.0)
    return float(np.sum(parts)) if parts else math.nan
