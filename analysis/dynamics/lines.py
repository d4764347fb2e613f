"""Spectral lines off a drive's harmonics: found against the local floor, fitted exactly.

One mechanism for every place that looks for a tone the drive did not make: the residual
reading names such lines as findings (:mod:`analysis.discrepancy.residual_reading`), and
the regime judge takes out the ones the pendulum cannot have made before it strobes
(:mod:`analysis.dynamics.measured_regime`).  On white noise a line shows with a chance
of at most FALSE_ALARM, whatever the record's length.
"""

from __future__ import annotations

import math

import numpy as np

# Chance that a residual of pure white noise shows a line (or any other finding of the
# residual reading): small enough that a benchmark of hundreds of clean records sees none.
FALSE_ALARM = 1e-4
# Spectrum: a Blackman-Harris window keeps a strong drive harmonic's leakage 92 dB down,
# so its skirts never pass for lines; its equivalent noise bandwidth is 2 bins.
WINDOW_BINS = 2.0
FLOOR_WINDOW = 513  # bins of the running median that is a line's local noise floor
RING = (8, 72)  # bins either side of a peak whose median it must also clear (a narrow line)
MERGE_BINS = 6  # peaks closer than this are one line (the window's main lobe is +-4 bins)
HARMONIC_GUARD_BINS = 6  # a peak this close to a drive harmonic is the harmonic's
LINE_MIN_CYCLES = 10  # a line makes at least this many cycles over the record (else: trend)
CLEAN_ROUNDS = 6  # fit-and-subtract rounds (gaps in the record leak a strong line's power)
LEAK_SAFETY = 10.0  # a peak is a line only this far above what the gaps leak from the strongest


def find_lines(
    t: np.ndarray, x: np.ndarray, ok: np.ndarray, base_hz: float | None, *,
    max_lines: int | None = None,
) -> list[tuple[float, float]]:
    """(frequency [Hz], amplitude) of the lines in ``x`` off the harmonics of ``base_hz``.

    ``t`` is uniform, ``ok`` marks the valid samples (``x`` finite there).  The periodic
    part at ``base_hz`` (all its harmonics at once, the average over each phase of the
    period) is taken out first, so that no harmonic leaks through the record's gaps;
    peaks near a harmonic are never lines.  Lines are then found in rounds: the strongest
    peaks that pass the threshold (and exceed what the gaps could leak from the
    strongest, ``_leakage``) are fitted by least squares on the valid samples, exact
    despite the gaps, and subtracted; the next round looks again.  Largest first.
    ``max_lines``: stop once that many are found, the strongest of each round first (a
    residual far from white can show hundreds, whose fit costs seconds and tells no more).
    """
    size = x.size
    dt = float(t[1] - t[0])
    df = 1.0 / (size * dt)
    first = max(LINE_MIN_CYCLES, RING[1])
    last = size // 2 - MERGE_BINS
    if last <= first:
        return []
    r = np.where(ok, x, 0.0)
    allowed = np.ones(size // 2 + 1, dtype=bool)
    if base_hz is not None:
        r = r - periodic_part(t, r, ok, base_hz)
        frequencies = np.arange(allowed.size) * df
        nearest = np.maximum(np.rint(frequencies / base_hz), 1.0) * base_hz
        allowed = np.abs(frequencies - nearest) > HARMONIC_GUARD_BINS * df
    threshold = line_threshold(int(np.count_nonzero(allowed[first:last])))
    leak = _leakage(ok)
    fitted: list[float] = []  # frequencies [Hz] of the lines fitted so far
    remaining = r
    for _ in range(CLEAN_ROUNDS):
        power = periodogram(np.where(ok, remaining - remaining[ok].mean(), 0.0), ok)
        ratio = np.where(allowed, power / local_floor(power), 0.0)
        found = [_refine(power, k) * df
                 for k in _peaks(ratio, power, first, last, threshold, leak)]
        found = [f for f in found if all(abs(f - g) > MERGE_BINS * df for g in fitted)]
        if max_lines is not None:
            found = found[: max_lines - len(fitted)]
        if not found:
            break
        fitted += found
        if max_lines is not None and len(fitted) >= max_lines:
            break
        remaining = r - fit_sines(t, r, ok, fitted)[0]
    if not fitted:
        return []
    _, amplitudes = fit_sines(t, r, ok, fitted)
    return sorted(((float(f), float(a)) for f, a in zip(fitted, amplitudes, strict=True)),
                  key=lambda fa: -fa[1])


def periodogram(filled: np.ndarray, ok: np.ndarray, *, window: bool = True) -> np.ndarray:
    """Periodogram of a zero-filled sequence (Blackman-Harris window, or none), scaled so
    that white noise of variance s^2 has every bin's expectation s^2 whatever the gaps
    (bins 0..n/2)."""
    from scipy import fft as sp_fft  # here: the map command needs no scipy.signal
    from scipy.signal import windows

    taper = windows.blackmanharris(filled.size, sym=False) if window else np.ones(filled.size)
    weight = taper * ok
    return np.abs(sp_fft.rfft(filled * taper)) ** 2 / float(weight @ weight)


def line_threshold(tested: int) -> float:
    """Power over the local floor that a bin of white noise passes with a chance of at most
    FALSE_ALARM / tested: e^-tau per bin for an exact floor, tau raised so that the floor's
    own scatter (the median of FLOOR_WINDOW / WINDOW_BINS independent bins, relative
    variance s2 = 2.08 / that count) costs nothing: E[exp(-tau (1 + e))] = exp(-tau +
    tau^2 s2 / 2) for a Gaussian error e."""
    level = math.log(max(tested, 1) / FALSE_ALARM)
    s2 = 2.08 * WINDOW_BINS / FLOOR_WINDOW
    return (1.0 - math.sqrt(1.0 - 2.0 * s2 * level)) / s2


def local_floor(power: np.ndarray) -> np.ndarray:
    """Per bin, the larger of the running median and the median of the ring of bins either
    side of it (a peak on a broad hump or on the skirt of low frequencies is no line)."""
    from scipy import ndimage

    wide = ndimage.median_filter(power, size=FLOOR_WINDOW, mode="reflect")
    ring = np.zeros(2 * RING[1] + 1, dtype=bool)
    ring[: RING[1] - RING[0] + 1] = True
    ring[RING[1] + RING[0]:] = True
    near = ndimage.median_filter(power, footprint=ring, mode="reflect")
    return np.maximum(wide, near) / math.log(2.0)


def periodic_part(t: np.ndarray, r: np.ndarray, ok: np.ndarray, base_hz: float) -> np.ndarray:
    """The average of ``r`` over each phase of the period 1 / base_hz (one bin a sample),
    read back at every sample's phase by linear interpolation round the period."""
    bins = max(8, round(1.0 / (base_hz * float(t[1] - t[0]))))
    position = ((t - t[0]) * base_hz % 1.0) * bins
    index = np.minimum(position.astype(np.int64), bins - 1)
    counts = np.bincount(index[ok], minlength=bins)
    sums = np.bincount(index[ok], weights=r[ok], minlength=bins)
    profile = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    centres = np.arange(bins) + 0.5
    return np.interp(position, centres, profile, period=bins)


def fit_sines(
    t: np.ndarray, r: np.ndarray, ok: np.ndarray, frequencies_hz: list[float]
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares sines at the given frequencies (and a constant) on the valid samples:
    the fitted curve over the whole record and each sine's amplitude.

    Lines are at least MERGE_BINS apart, so their sines are nearly orthogonal and the
    normal equations are well conditioned: solved by Cholesky, many times faster than an
    SVD of the samples (an orthogonal solve is the fallback should they not be)."""
    from scipy import linalg

    tt = t - t[0]
    phase = (2.0 * math.pi) * np.outer(tt, np.asarray(frequencies_hz, dtype=float))
    basis = np.empty((tt.size, 2 * phase.shape[1] + 1))
    basis[:, 0] = 1.0
    basis[:, 1::2] = np.sin(phase)
    basis[:, 2::2] = np.cos(phase)
    used = basis[ok]
    try:
        coef = linalg.cho_solve(linalg.cho_factor(used.T @ used), used.T @ r[ok])
    except linalg.LinAlgError:
        coef = linalg.lstsq(used, r[ok])[0]
    return basis @ coef, np.hypot(coef[1::2], coef[2::2])


def _leakage(ok: np.ndarray) -> float:
    """The largest share of a line's power that the record's gaps move to another bin
    beyond the window's main lobe (0 without gaps)."""
    if ok.all():
        return 0.0
    mask = periodogram(ok.astype(float), np.ones_like(ok))
    return float(mask[MERGE_BINS:].max() / mask[0])


def _peaks(ratio, power, first, last, threshold, leak) -> list[int]:
    """Bins that pass ``threshold``, are the largest within MERGE_BINS and stand above
    what the gaps could leak from this round's strongest peak."""
    candidates = np.flatnonzero(ratio[first:last] > threshold) + first
    if candidates.size == 0:
        return []
    strongest = float(power[candidates].max())
    peaks = []
    for k in candidates[np.argsort(-power[candidates])]:
        if any(abs(k - j) <= MERGE_BINS for j in peaks):
            continue
        if power[k] < LEAK_SAFETY * leak * strongest:
            break
        peaks.append(int(k))
    return peaks


def _refine(power: np.ndarray, k: int) -> float:
    """The peak's position in bins: a parabola through the log power of three bins."""
    a, b, c = np.log(np.maximum(power[k - 1: k + 2], 1e-300))
    curvature = a - 2.0 * b + c
    return k + (0.5 * (a - c) / curvature if curvature < 0 else 0.0)
