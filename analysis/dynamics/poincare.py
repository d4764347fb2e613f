"""Poincare sections: once-per-drive-period samples of (theta, theta'), and the delayed-angle map.

Measured records mark each drive period with a tachometer pulse; simulations know the
drive phase.  Both end in the same :class:`PoincareSection`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PoincareSection:
    """Stroboscopic samples, one per drive period (angle [rad], rate [rad/s], time [s])."""

    theta: np.ndarray
    theta_dot: np.ndarray
    time_s: np.ndarray

    def __len__(self) -> int:
        return int(self.theta.size)

    @property
    def points(self) -> np.ndarray:
        """(n, 2) array of (theta, theta_dot), the form the classifier takes."""
        return np.column_stack([self.theta, self.theta_dot])

    def tail(self, count: int) -> PoincareSection:
        """The last ``count`` samples (drop the transient)."""
        return PoincareSection(self.theta[-count:], self.theta_dot[-count:], self.time_s[-count:])


def smoothed_derivative(x: np.ndarray, fs_hz: float, *, window_samples: int = 15) -> np.ndarray:
    """d/dt of a sampled signal by a cubic Savitzky-Golay filter (noise-robust finite difference).

    A potentiometer angle is noisy; differentiating it raw amplifies the noise by fs,
    so fit a local cubic over ``window_samples`` (odd) and differentiate the fit.
    """
    x = np.asarray(x, dtype=float)
    window = int(window_samples) | 1
    if window < 5:
        raise ValueError(f"window_samples = {window_samples}: need at least 5 for a cubic fit")
    if x.size < window:
        raise ValueError(f"signal of {x.size} samples is shorter than the {window}-sample window")
    from scipy.signal import savgol_filter  # here: the map command needs no scipy.signal

    return savgol_filter(x, window, 3, deriv=1, delta=1.0 / fs_hz, mode="interp")


def poincare_from_pulses(
    theta: np.ndarray,
    fs_hz: float,
    pulse_indices: np.ndarray,
    *,
    derivative_window_samples: int = 15,
) -> PoincareSection:
    """Section of a measured record at its tachometer pulses (sample indices, may be fractional).

    theta and a smoothed theta' are interpolated (cubic spline) at each pulse; pulses
    outside the record are refused rather than extrapolated.
    """
    theta = np.asarray(theta, dtype=float)
    pulses = np.asarray(pulse_indices, dtype=float).ravel()
    if theta.ndim != 1:
        raise ValueError(f"theta must be 1-D, got shape {theta.shape}")
    if pulses.size and (pulses.min() < 0 or pulses.max() > theta.size - 1):
        raise ValueError(
            f"pulse indices must lie in [0, {theta.size - 1}] (the record), "
            f"got [{pulses.min()}, {pulses.max()}]"
        )
    if np.any(np.diff(pulses) <= 0):
        raise ValueError("pulse indices must be strictly increasing")
    from scipy.interpolate import CubicSpline

    rate = smoothed_derivative(theta, fs_hz, window_samples=derivative_window_samples)
    index = np.arange(theta.size, dtype=float)
    theta_at = CubicSpline(index, theta)(pulses)
    rate_at = CubicSpline(index, rate)(pulses)
    return PoincareSection(theta_at, rate_at, pulses / fs_hz)


def poincare_from_phase(
    time_s: np.ndarray,
    theta: np.ndarray,
    drive_frequency_hz: float,
    *,
    theta_dot: np.ndarray | None = None,
    phase_rad: float = 0.0,
    derivative_window_samples: int = 15,
) -> PoincareSection:
    """Section of a uniformly sampled run at drive phase ``phase_rad`` (Omega t = 2 pi k + phase).

    ``theta_dot`` is used when known (simulations); otherwise it is a smoothed derivative.
    """
    time_s = np.asarray(time_s, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if time_s.shape != theta.shape or time_s.ndim != 1 or time_s.size < 2:
        raise ValueError("time_s and theta must be 1-D arrays of the same length (>= 2)")
    if not drive_frequency_hz > 0:
        raise ValueError(f"drive_frequency_hz = {drive_frequency_hz!r}: must be > 0")
    fs_hz = 1.0 / float(np.median(np.diff(time_s)))
    if theta_dot is None:
        theta_dot = smoothed_derivative(theta, fs_hz, window_samples=derivative_window_samples)
    period = 1.0 / drive_frequency_hz
    offset = (phase_rad / (2.0 * np.pi)) * period
    first = np.ceil((time_s[0] - offset) / period - 1e-9)
    last = np.floor((time_s[-1] - offset) / period + 1e-9)
    times = offset + period * np.arange(first, last + 1)
    from scipy.interpolate import CubicSpline

    spline_theta = CubicSpline(time_s, theta)
    spline_rate = CubicSpline(time_s, np.asarray(theta_dot, dtype=float))
    return PoincareSection(spline_theta(times), spline_rate(times), times)


def delayed_map(values: np.ndarray, delay: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (x_k, x_{k+delay}) of a once-per-period series: the delayed-angle Poincare map."""
    values = np.asarray(values, dtype=float).ravel()
    if delay < 1 or values.size <= delay:
        raise ValueError(f"need more than delay = {delay} samples, got {values.size}")
    return values[:-delay], values[delay:]
