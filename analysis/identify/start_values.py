"""Starting values for decay fits read off the data: FFT and turning points, log decrement."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.identify.preprocess import (
    PreparedSignal,
    centre_estimate,
    side_crossings,
    turning_points,
)
from analysis.identify.result import IdentificationError

MIN_SAMPLES_PER_PERIOD = 8
MIN_PERIODS = 1.5


@dataclass(frozen=True)
class DecayGuess:
    """First estimates of a damped swing theta = c + A e^(-zeta omega t) cos(omega t + phi)."""

    omega_rad_s: float
    zeta: float
    amplitude_rad: float
    phase_rad: float
    offset_rad: float
    turning_times_s: np.ndarray
    turning_amplitudes_rad: np.ndarray


def _require_periods(signal: PreparedSignal, centred: np.ndarray) -> None:
    """Refuse a record shorter than MIN_PERIODS periods, naming its period as its zero
    crossings give it: over a period or two the spectrum's peak is too broad to tell it.

    Crossings two apart span one period whatever the error of the centre, so a period is
    only named when the record holds one."""
    t = signal.time_s
    duration = t[-1] - t[0]
    used = f"{duration:.4g} s"
    trimmed = signal.trim_start_s + signal.trim_end_s
    if trimmed > 0:
        used += f" (left after trimming {trimmed:.3g} s before the release or at rest)"
    crossings = side_crossings(centred)
    if crossings.size < 3:
        raise IdentificationError(
            f"record too short: {used} holds less than one period of the swing (it crosses "
            f"its centre {crossings.size} time(s)); need at least {MIN_PERIODS} periods"
        )
    period = float(np.median(t[crossings[2:]] - t[crossings[:-2]]))
    if duration < MIN_PERIODS * period:
        raise IdentificationError(
            f"record too short: {used} is {duration / period:.2g} periods of "
            f"{period:.4g} s (from its zero crossings); need at least {MIN_PERIODS}"
        )


def guess_decay(signal: PreparedSignal) -> DecayGuess:
    """Frequency from the FFT peak refined by turning points; damping from the log decrement."""
    t = signal.time_s
    good = signal.valid
    if np.count_nonzero(good) < 16:
        raise IdentificationError("too few usable samples to fit")
    idx = np.arange(t.size)
    filled = np.interp(idx, idx[good], signal.angle_rad[good])
    centre = centre_estimate(filled)
    dt = float(np.mean(np.diff(t)))
    centred = filled - centre
    size = 1 << math.ceil(math.log2(4 * t.size))
    spectrum = np.abs(np.fft.rfft(centred * np.hanning(t.size), size))
    freqs = np.fft.rfftfreq(size, dt)
    spectrum[freqs < 1.0 / (t[-1] - t[0] + dt)] = 0.0  # below one cycle per record: drift
    peak = int(np.argmax(spectrum))
    if peak == 0 or spectrum[peak] <= 0:
        raise IdentificationError("no oscillation found in the record (flat spectrum)")
    period = 1.0 / freqs[peak]
    samples_per_period = period / dt
    if samples_per_period < MIN_SAMPLES_PER_PERIOD:
        raise IdentificationError(
            f"too few samples per period: {samples_per_period:.3g} (period {period:.4g} s at "
            f"{1 / dt:.4g} Hz); need at least {MIN_SAMPLES_PER_PERIOD}"
        )
    duration = t[-1] - t[0]
    if duration < MIN_PERIODS * period:
        _require_periods(signal, centred)
    turns = turning_points(filled, centre, signal.noise_rad, max(2, int(samples_per_period / 4)))
    if turns.size < 3:
        raise IdentificationError(
            f"no oscillation: only {turns.size} turning point(s) above the noise "
            f"({signal.noise_rad:.3g} rad)"
        )
    turn_t = t[turns]
    # Offset: midpoints of successive swings (a decaying swing biases each by half its decay,
    # averaging neighbours cancels that to first order).
    mids = 0.5 * (filled[turns][:-1] + filled[turns][1:])
    offset = float(np.median(mids)) if mids.size else centre
    amplitudes = np.abs(filled[turns] - offset)
    half_periods = np.diff(turn_t)
    period = 2.0 * float(np.median(half_periods))
    omega = 2.0 * math.pi / period
    positive = amplitudes > 3.0 * signal.noise_rad
    if np.count_nonzero(positive) >= 2:
        slope, intercept = np.polyfit(turn_t[positive], np.log(amplitudes[positive]), 1)
        zeta = float(np.clip(-slope / omega, 1e-5, 0.5))
        amplitude = float(math.exp(intercept))
    else:
        zeta, amplitude = 1e-3, float(amplitudes.max())
    # Phase from a linear fit of the first period with omega and the decay fixed.
    first = (t < t[0] + period) & good
    envelope = np.exp(-zeta * omega * t[first])
    basis = np.column_stack(
        [envelope * np.cos(omega * t[first]), envelope * np.sin(omega * t[first])]
    )
    (a, b), *_ = np.linalg.lstsq(basis, filled[first] - offset, rcond=None)
    phase = math.atan2(-b, a)
    amplitude = max(amplitude, math.hypot(a, b))
    return DecayGuess(omega, zeta, amplitude, phase, offset, turn_t, amplitudes)
