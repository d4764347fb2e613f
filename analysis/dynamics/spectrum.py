"""Windowed amplitude spectra with peaks named as rational multiples of the drive frequency.

Sub- and superharmonics are what tell a period-n response from a period-1 one, so each
peak is labelled ``"1/2 f"``, ``"f"``, ``"3 f"``, ``"2/3 f"`` (or by its decimal ratio
when no small fraction fits, as for an incommensurate, quasi-periodic line).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np


@dataclass(frozen=True)
class SpectralPeak:
    """One spectral line: where it is, how big, and its ratio to the drive frequency."""

    frequency_hz: float
    amplitude: float
    ratio: float
    harmonic: Fraction | None  # small fraction p/q matching ratio, None when none fits
    label: str


@dataclass(frozen=True)
class Spectrum:
    """One-sided amplitude spectrum: a sine of amplitude a shows a line of height ~a."""

    frequency_hz: np.ndarray
    amplitude: np.ndarray
    drive_frequency_hz: float | None
    window: str
    peaks: tuple[SpectralPeak, ...]

    @property
    def amplitude_db(self) -> np.ndarray:
        """20 log10 of the amplitude relative to the largest line (log scale for plots)."""
        top = float(np.max(self.amplitude)) if self.amplitude.size else 1.0
        floor = np.finfo(float).tiny
        return 20.0 * np.log10(np.maximum(self.amplitude, floor) / max(top, floor))

    @property
    def labels(self) -> tuple[str, ...]:
        """Labels of the peaks, largest first."""
        return tuple(peak.label for peak in self.peaks)


def harmonic_label(ratio: Fraction) -> str:
    """Text for a multiple of the drive frequency: '1/2 f', 'f', '3 f', '2/3 f'."""
    if ratio == 0:
        return "0"
    if ratio == 1:
        return "f"
    if ratio.denominator == 1:
        return f"{ratio.numerator} f"
    return f"{ratio.numerator}/{ratio.denominator} f"


def name_ratio(
    frequency_hz: float,
    drive_frequency_hz: float,
    *,
    tolerance_hz: float,
    max_denominator: int = 6,
) -> tuple[Fraction | None, str]:
    """The smallest-denominator fraction p/q within ``tolerance_hz`` of the line, and its label.

    Small denominators are tried first so that a line at exactly f/2 is never named
    5/11 f; when nothing fits the label is the decimal ratio, e.g. '0.618 f'.
    """
    ratio = frequency_hz / drive_frequency_hz
    for q in range(1, max_denominator + 1):
        p = round(ratio * q)
        if p <= 0:
            continue
        if abs(p / q * drive_frequency_hz - frequency_hz) <= tolerance_hz:
            fraction = Fraction(p, q)
            return fraction, harmonic_label(fraction)
    return None, f"{ratio:.3g} f"


def amplitude_spectrum(
    x: np.ndarray,
    fs_hz: float,
    *,
    drive_frequency_hz: float | None = None,
    window: str = "hann",
    detrend: bool = True,
    max_peaks: int = 12,
    dynamic_range_db: float = 60.0,
    max_denominator: int = 6,
) -> Spectrum:
    """Amplitude spectrum of ``x`` (e.g. the angle) with its main peaks found and labelled.

    The window's coherent gain is divided out so line heights are signal amplitudes.
    Peaks are kept when they stand at least 6 dB above their surroundings and within
    ``dynamic_range_db`` of the largest line; each frequency is refined by a parabola
    through the log amplitudes of the three top bins.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 8:
        raise ValueError(f"x must be a 1-D signal of at least 8 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x contains NaN or infinite samples; cut or fill the gaps first")
    if not fs_hz > 0:
        raise ValueError(f"fs_hz = {fs_hz!r}: the sampling rate must be > 0")
    if drive_frequency_hz is not None and not drive_frequency_hz > 0:
        raise ValueError(f"drive_frequency_hz = {drive_frequency_hz!r}: must be > 0 or None")
    n = x.size
    if detrend:
        x = x - np.mean(x)
    from scipy.signal import get_window  # here: the map command needs no scipy.signal

    taper = get_window(window, n, fftbins=True)
    coherent_gain = float(np.sum(taper))
    amplitude = np.abs(np.fft.rfft(x * taper)) * 2.0 / coherent_gain
    amplitude[0] *= 0.5
    frequency = np.fft.rfftfreq(n, d=1.0 / fs_hz)
    peaks = _find_peaks(
        frequency, amplitude, drive_frequency_hz, max_peaks, dynamic_range_db, max_denominator
    )
    return Spectrum(frequency, amplitude, drive_frequency_hz, window, peaks)


def _find_peaks(
    frequency: np.ndarray,
    amplitude: np.ndarray,
    drive_frequency_hz: float | None,
    max_peaks: int,
    dynamic_range_db: float,
    max_denominator: int,
) -> tuple[SpectralPeak, ...]:
    floor = np.finfo(float).tiny
    level_db = 20.0 * np.log10(np.maximum(amplitude, floor))
    level_db[0] = -np.inf  # the mean is not a line
    top = float(np.max(level_db[1:])) if level_db.size > 1 else -np.inf
    if not np.isfinite(top):
        return ()
    level_db = np.maximum(level_db, top - dynamic_range_db - 40.0)
    from scipy.signal import find_peaks

    index, _ = find_peaks(level_db, prominence=6.0, height=top - dynamic_range_db)
    index = index[np.argsort(amplitude[index])[::-1]][:max_peaks]
    bin_hz = frequency[1] - frequency[0]
    found = []
    for i in index:
        f_peak, a_peak = _refine(frequency, level_db, i, bin_hz)
        if drive_frequency_hz is None:
            found.append(SpectralPeak(f_peak, a_peak, float("nan"), None, f"{f_peak:.4g} Hz"))
            continue
        # A Hann main lobe is 4 bins wide; a line within one bin of p/q f is that harmonic.
        fraction, label = name_ratio(
            f_peak, drive_frequency_hz, tolerance_hz=bin_hz, max_denominator=max_denominator
        )
        found.append(SpectralPeak(f_peak, a_peak, f_peak / drive_frequency_hz, fraction, label))
    return tuple(found)


def _refine(
    frequency: np.ndarray, level_db: np.ndarray, i: int, bin_hz: float
) -> tuple[float, float]:
    """Parabolic interpolation of a peak on the dB scale (frequency, linear amplitude)."""
    if 0 < i < level_db.size - 1:
        left, centre, right = level_db[i - 1], level_db[i], level_db[i + 1]
        curvature = left - 2.0 * centre + right
        if curvature < 0:
            shift = 0.5 * (left - right) / curvature
            peak_db = centre - 0.25 * (left - right) * shift
            return float(frequency[i] + shift * bin_hz), float(10.0 ** (peak_db / 20.0))
    return float(frequency[i]), float(10.0 ** (level_db[i] / 20.0))
