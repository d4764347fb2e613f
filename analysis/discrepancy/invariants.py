"""Statistics of a forced record that a chaotic response keeps even though its trajectory
cannot be predicted point by point: the distribution of the Poincare section (angle at
drive phase 0), the distribution of the swing's upper turning points (where impacts
stop it) and the power at the drive's harmonics and subharmonics.

Two records (or a record and a simulation) are compared by the earth mover's
distance of the two distributions (in units of the angle's spread) and the mean
absolute difference of the spectral lines in decibels; a model whose invariants lie
closer to the data's explains it better.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import welch
from scipy.stats import wasserstein_distance

LINES_PER_HARMONIC = 6  # multiples of f/6 cover period 2 and 3 subharmonics
MAX_HARMONIC = 5
LINE_FLOOR_DB = -60.0


@dataclass(frozen=True)
class Invariants:
    """Invariant statistics of one forced run."""

    poincare_rad: np.ndarray
    turning_points_rad: np.ndarray
    line_power_db: np.ndarray  # power at k f / 6, k = 1 .. 6 * MAX_HARMONIC
    scale_rad: float  # standard deviation of the angle: the unit of the distribution distances


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
    turning = upper_turning_points(filled)
    fs = 1.0 / float(t[1] - t[0])
    nper = min(filled.size, round(8 * fs * period))
    freqs, power = welch(filled - filled.mean(), fs=fs, nperseg=max(nper, 16))
    lines = frequency_hz * np.arange(1, LINES_PER_HARMONIC * MAX_HARMONIC + 1) / LINES_PER_HARMONIC
    lines = lines[lines < 0.5 * fs]
    line_power = np.interp(lines, freqs, power)
    total = float(np.sum(power)) or 1.0
    # lines far below the motion's power are noise floor, not structure: clip them
    db = 10.0 * np.log10(line_power / total + 1e-300)
    return Invariants(poincare, turning, np.maximum(db, LINE_FLOOR_DB),
                      float(np.std(filled)) or 1.0)


def upper_turning_points(theta: np.ndarray) -> np.ndarray:
    """Largest angle of each excursion above the centre (noise-proof: an excursion must rise
    a quarter of the spread above the median)."""
    centred = theta - np.median(theta)
    above = np.concatenate([[False], centred > 0.25 * np.std(centred), [False]])
    edges = np.flatnonzero(above[1:] != above[:-1])
    return np.array([theta[a:b].max() for a, b in zip(edges[0::2], edges[1::2], strict=True)])


def invariant_distance(a: Invariants, b: Invariants) -> float:
    """Earth mover's distances of the Poincare and turning-point distributions (in units of
    ``a``'s angle spread) plus the mean spectral-line difference (in units of 20 dB): 0 for
    identical statistics."""
    parts = []
    for x, y in ((a.poincare_rad, b.poincare_rad), (a.turning_points_rad, b.turning_points_rad)):
        if x.size >= 5 and y.size >= 5:
            parts.append(float(wasserstein_distance(x, y)) / a.scale_rad)
    n = min(a.line_power_db.size, b.line_power_db.size)
    if n:
        parts.append(float(np.mean(np.abs(a.line_power_db[:n] - b.line_power_db[:n]))) / 20.0)
    return float(np.sum(parts)) if parts else math.nan
