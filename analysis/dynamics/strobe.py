"""Stroboscopic sampling of a forced record, locked to its drive: the strobe clock and the points.

The clock t_k = t0 + k T is fitted to the tachometer pulses (which mark drive phase 0,
docs/MODEL.md section 6) so that a missing, doubled or one-sample-late pulse moves no
strobe instant; without a tach it follows the stated frequency and phase.  Each
period gives one point: the angle at ``phases_per_period`` equally spaced drive
phases, each from a local polynomial fit over a few samples (less noise than one
sample, and a known noise gain, which the regime judgement needs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis import quantities as q

# A pulse more than this far from the fitted clock is not a drive-phase-0 mark (an extra
# pulse, a bounce); one sample of quantisation jitter stays well inside it.
PULSE_TOLERANCE_SAMPLES = 3.0
PULSE_TOLERANCE_FRACTION = 0.05  # ... or this fraction of a period, when that is larger
MIN_PULSES = 3
# The tach line is sampled with the analog inputs (docs/daq_protocol.md): a pulse shows on
# the first sample at or after it, so it happened on average half a sample before its mark.
PULSE_MARK_LAG_SAMPLES = 0.5
MIN_PERIOD_SAMPLES = 8  # a drive period shorter than this cannot be strobed at several phases


@dataclass(frozen=True)
class StrobeClock:
    """Drive-phase-0 instants t_k = first_index + k period_samples, in samples of the record.

    ``source`` is 'tach' (fitted to the pulses) or 'stated' (from a given frequency and
    phase).  For a tach clock, ``pulses_used`` lie on the clock; ``extra_pulses`` (off
    the clock or a second pulse in one period) and ``missing_pulses`` (periods between
    the first and last used pulse without one) are counted, ``jitter_rms_samples`` is
    the RMS distance of the used pulses from the clock, and :meth:`timing_se_samples`
    how well the fitted clock places an instant.
    """

    fs_hz: float
    first_index: float  # the first phase-0 instant at or after sample 0
    period_samples: float
    source: str
    period_se_samples: float = 0.0  # standard error of the fitted period (0 when stated)
    centre_index: float = 0.0  # the fitted pulses' centre, where the clock is best known
    centre_se_samples: float = 0.0  # standard error of the clock there
    pulses_used: int = 0
    extra_pulses: int = 0
    missing_pulses: int = 0
    jitter_rms_samples: float = 0.0
    stated_frequency_hz: float | None = None

    @property
    def frequency_hz(self) -> float:
        """The drive frequency the clock runs at (measured for a tach clock)."""
        return self.fs_hz / self.period_samples

    @property
    def frequency_se_hz(self) -> float:
        """Standard error of ``frequency_hz`` (0 for a stated clock)."""
        return self.frequency_hz * self.period_se_samples / self.period_samples

    @property
    def period_s(self) -> float:
        """Drive period [s]."""
        return self.period_samples / self.fs_hz

    @property
    def phase_at_start_rad(self) -> float:
        """Drive phase at sample 0 in (-pi, pi]: x_t = A sin(2 pi f t + phase), t from sample 0."""
        return float(math.remainder(-2.0 * math.pi * self.first_index / self.period_samples,
                                    2.0 * math.pi))

    def timing_se_samples(self, instants: np.ndarray) -> np.ndarray:
        """Standard error [samples] of the clock's time at ``instants`` (sample indices): the
        fitted line's, least at the pulses' centre and growing with the period's error."""
        periods_away = (np.asarray(instants, dtype=float) - self.centre_index) / self.period_samples
        return np.sqrt(self.centre_se_samples**2 + (periods_away * self.period_se_samples) ** 2)

    def summary(self) -> dict[str, float | int | str | None]:
        """The clock as plain values (for evidence and reports)."""
        return {
            "source": self.source,
            q.frequency_hz: self.frequency_hz,
            "frequency_se_hz": self.frequency_se_hz,
            "phase_at_start_rad": self.phase_at_start_rad,
            "stated_frequency_hz": self.stated_frequency_hz,
            "pulses_used": self.pulses_used,
            "extra_pulses": self.extra_pulses,
            "missing_pulses": self.missing_pulses,
            "jitter_rms_samples": self.jitter_rms_samples,
        }


def clock_from_tach(
    pulse_indices: np.ndarray,
    fs_hz: float,
    *,
    stated_frequency_hz: float | None = None,
) -> StrobeClock:
    """Fit t_k = t0 + k T to tach pulses (sample indices; missing, extra or jittered ones allowed).

    A pulse index is the sample where the sampled tach line first reads high; the pulse
    itself is taken half a sample earlier (PULSE_MARK_LAG_SAMPLES).

    The rough period is the typical pulse spacing, or the stated one when that places
    the pulses better (more pulses on the clock, fewer periods without one: many
    doubled pulses spoil the spacing; a wrong stated frequency places few).  Each
    pulse is numbered by the whole periods since the previous accepted pulse, so a
    missing pulse skips a number and an extra one (off the clock, or a second one in
    the same period) is left out; a least-squares line through the accepted pulses,
    renumbered and refitted without the pulses it leaves off, is the clock.
    """
    _check_rate(fs_hz)
    pulses = np.unique(np.asarray(pulse_indices, dtype=float).ravel())
    if not np.all(np.isfinite(pulses)):
        raise ValueError("tach pulse indices contain NaN or infinite values")
    pulses = pulses - PULSE_MARK_LAG_SAMPLES
    if pulses.size < MIN_PULSES:
        raise ValueError(
            f"{pulses.size} tach pulse(s): need at least {MIN_PULSES} to fit the drive clock"
        )
    candidates = [_typical_spacing(np.diff(pulses))]
    if stated_frequency_hz is not None:
        _check_frequency(stated_frequency_hz)
        candidates.append(fs_hz / stated_frequency_hz)
    rough, numbers, used = max(
        ((period, *_number_pulses(pulses, period)) for period in candidates),
        key=lambda candidate: _placement_score(candidate[1], candidate[2]),
    )
    if used.sum() < MIN_PULSES or rough < MIN_PERIOD_SAMPLES:
        raise ValueError(
            "the tach pulses do not follow a steady drive clock "
            f"(a period of {rough:.4g} samples places {int(used.sum())} of {pulses.size} pulses)"
        )
    for _ in range(2):  # renumber from the fitted line, keep the pulses on it
        t0, period, _, _ = _line(numbers[used], pulses[used])
        numbers = np.rint((pulses - t0) / period)
        distance = np.abs(pulses - (t0 + numbers * period))
        used = _one_per_period(numbers, distance, distance <= _tolerance(period))
    t0, period, se, residual = _line(numbers[used], pulses[used])
    span = int(numbers[used].max() - numbers[used].min()) + 1
    first = t0 - math.floor(t0 / period) * period
    jitter = _pulse_jitter(residual)
    return StrobeClock(
        fs_hz=float(fs_hz),
        first_index=float(first),
        period_samples=float(period),
        source="tach",
        period_se_samples=float(se),
        centre_index=float(np.mean(pulses[used])),
        centre_se_samples=jitter / math.sqrt(used.sum()),
        pulses_used=int(used.sum()),
        extra_pulses=int(pulses.size - used.sum()),
        missing_pulses=int(span - used.sum()),
        jitter_rms_samples=float(np.sqrt(np.mean(residual**2))),
        stated_frequency_hz=None if stated_frequency_hz is None else float(stated_frequency_hz),
    )


def clock_from_drive(frequency_hz: float, fs_hz: float, *, phase_rad: float = 0.0) -> StrobeClock:
    """The clock of a drive x_t = A sin(2 pi f t + phase_rad), t counted from sample 0."""
    _check_rate(fs_hz)
    _check_frequency(frequency_hz)
    if not math.isfinite(phase_rad):
        raise ValueError(f"phase_rad = {phase_rad!r}: must be finite")
    period = fs_hz / frequency_hz
    first = ((-phase_rad / (2.0 * math.pi)) % 1.0) * period
    return StrobeClock(
        fs_hz=float(fs_hz), first_index=float(first), period_samples=float(period),
        source="stated", stated_frequency_hz=float(frequency_hz),
    )


@dataclass(frozen=True)
class StrobeSamples:
    """One point per whole drive period of a record: the angle at equally spaced drive phases.

    ``points[n, j]`` is the angle [rad] at drive phase 2 pi j / d of period
    ``periods[n]`` (consecutive), from a local fit; its noise is the record's sample
    noise times ``noise_gain[n, j]`` (the norm of the fit's weights), and
    ``timing_noise_rad[n, j]`` from the clock's uncertainty (the angle's slope times
    the clock's standard error there; 0 for a stated clock).  A point whose fit window
    holds a missing (NaN) sample is NaN.  ``time_s`` is each period's phase-0 instant,
    from sample 0.
    """

    points: np.ndarray
    noise_gain: np.ndarray
    timing_noise_rad: np.ndarray
    periods: np.ndarray
    time_s: np.ndarray
    clock: StrobeClock
    window_samples: int
    degree: int

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def phases_per_period(self) -> int:
        """Number of drive phases per point (the points' dimension)."""
        return int(self.points.shape[1])

    @property
    def section(self) -> np.ndarray:
        """The Poincare section at the tach: the angle at drive phase 0 of each period."""
        return self.points[:, 0]

    def start_sample(self, row: int) -> int:
        """First sample of the period of ``row`` (where the settled part of a record begins)."""
        return max(0, math.floor(self.time_s[row] * self.clock.fs_hz))


def strobe_samples(
    theta: np.ndarray,
    clock: StrobeClock,
    *,
    phases_per_period: int = 8,
    window_samples: int | None = None,
    degree: int = 2,
) -> StrobeSamples:
    """Sample ``theta`` at ``phases_per_period`` drive phases of every whole period in the record.

    Each value is a degree-``degree`` polynomial fitted by least squares to the
    ``window_samples`` samples nearest the instant (default: about a 32nd of a
    period, odd, 5 to 31 samples), evaluated at the instant.  Periods whose windows
    reach past either end of the record are left out.
    """
    theta = np.asarray(theta, dtype=float)
    if theta.ndim != 1:
        raise ValueError(f"theta must be 1-D, got shape {theta.shape}")
    if phases_per_period < 1:
        raise ValueError(f"phases_per_period = {phases_per_period}: need at least 1")
    if window_samples is None:
        window_samples = int(np.clip(round(clock.period_samples / 32.0), 5, 31))
    window = int(window_samples) | 1
    if window < degree + 2:
        raise ValueError(
            f"window_samples = {window_samples}: need at least degree + 2 = {degree + 2} "
            "samples to fit the local polynomial and know its noise"
        )
    if window > clock.period_samples / phases_per_period:
        raise ValueError(
            f"window_samples = {window} reaches past the next strobe phase "
            f"({clock.period_samples / phases_per_period:.3g} samples apart): use fewer phases "
            "or a shorter window"
        )
    half = window // 2
    step = clock.period_samples / phases_per_period
    # periods k whose every phase instant has its whole window inside the record
    first_k = math.ceil((half + 0.5 - clock.first_index) / clock.period_samples)
    last_instant = theta.size - 1 - half - 0.5
    last_k = math.floor(
        (last_instant - clock.first_index - (phases_per_period - 1) * step) / clock.period_samples
    )
    periods = np.arange(first_k, last_k + 1)
    if periods.size == 0:
        raise ValueError(
            f"the record ({theta.size} samples) holds no whole drive period of "
            f"{clock.period_samples:.4g} samples"
        )
    instants = (
        clock.first_index
        + periods[:, None] * clock.period_samples
        + np.arange(phases_per_period)[None, :] * step
    )
    values, gains, slopes = _local_fit(theta, instants.ravel(), half, degree)
    shape = instants.shape
    timing = np.abs(slopes) * clock.timing_se_samples(instants.ravel())
    return StrobeSamples(
        points=values.reshape(shape),
        noise_gain=gains.reshape(shape),
        timing_noise_rad=timing.reshape(shape),
        periods=periods,
        time_s=instants[:, 0] / clock.fs_hz,
        clock=clock,
        window_samples=window,
        degree=int(degree),
    )


def strobe_record(
    theta: np.ndarray,
    fs_hz: float,
    *,
    tach_indices: np.ndarray | None = None,
    frequency_hz: float | None = None,
    phase_rad: float = 0.0,
    phases_per_period: int = 8,
) -> StrobeSamples:
    """Strobe a forced record: on its tach clock when it has pulses, else on the stated drive.

    ``frequency_hz`` (the stated drive) is compared with the tach in the clock's
    summary; without pulses it and ``phase_rad`` (drive phase at sample 0) set the clock.
    """
    pulses = np.zeros(0) if tach_indices is None else np.asarray(tach_indices, dtype=float)
    if pulses.size >= MIN_PULSES:
        clock = clock_from_tach(pulses, fs_hz, stated_frequency_hz=frequency_hz)
    elif frequency_hz is not None:
        clock = clock_from_drive(frequency_hz, fs_hz, phase_rad=phase_rad)
    else:
        raise ValueError(
            f"{pulses.size} tach pulse(s) and no stated drive frequency: "
            "nothing to lock the strobe to"
        )
    return strobe_samples(theta, clock, phases_per_period=phases_per_period)


def _local_fit(
    theta: np.ndarray, instants: np.ndarray, half: int, degree: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value at each instant of a polynomial fitted to the 2 half + 1 nearest samples, the
    norm of its weights (the noise gain: white noise sigma gives sigma * gain) and its
    slope [per sample]."""
    centre = np.rint(instants).astype(np.int64)
    offsets = np.arange(-half, half + 1)
    index = centre[:, None] + offsets[None, :]
    # scaled abscissae keep the normal equations well conditioned
    u = (index - instants[:, None]) / max(half, 1)
    design = u[:, :, None] ** np.arange(degree + 1)[None, None, :]
    normal = np.einsum("nwi,nwj->nij", design, design)
    # rows of the fit's solution: the value (coefficient 0) and the slope (coefficient 1)
    unit = np.zeros((instants.size, degree + 1, 2))
    unit[:, 0, 0] = 1.0
    unit[:, 1, 1] = 1.0
    solution = np.linalg.solve(normal, unit)
    weights = np.einsum("nwi,ni->nw", design, solution[:, :, 0])
    slope_weights = np.einsum("nwi,ni->nw", design, solution[:, :, 1]) / max(half, 1)
    samples = theta[index]
    values = np.sum(weights * samples, axis=1)
    slopes = np.sum(slope_weights * samples, axis=1)
    return values, np.sqrt(np.sum(weights**2, axis=1)), slopes


def _typical_spacing(spacing: np.ndarray) -> float:
    """Pulse spacing of most periods: the mean of the spacings near the median (so that the
    one-sample quantisation averages out and a missing or extra pulse does not count)."""
    median = float(np.median(spacing))
    near = spacing[np.abs(spacing - median) <= max(1.0, 0.1 * median)]
    return float(np.mean(near))


def _tolerance(period: float) -> float:
    return max(PULSE_TOLERANCE_SAMPLES, PULSE_TOLERANCE_FRACTION * period)


def _number_pulses(pulses: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """Period number of each pulse and whether it lies on the clock.

    Counting starts at the first pulse followed one period later by another (so an
    extra pulse at the start cannot be the anchor) and runs both ways, each pulse
    numbered by the whole periods since the previous accepted one and accepted when
    it is within the tolerance of that whole number.
    """
    tolerance = _tolerance(period)
    regular = np.flatnonzero(np.abs(np.diff(pulses) - period) <= tolerance)
    anchor = int(regular[0]) if regular.size else 0
    later_numbers, later_used = _count_on(pulses[anchor:] - pulses[anchor], period, tolerance)
    earlier_numbers, earlier_used = _count_on(
        pulses[anchor] - pulses[anchor::-1], period, tolerance
    )
    numbers = np.concatenate([-earlier_numbers[:0:-1], later_numbers])
    used = np.concatenate([earlier_used[:0:-1], later_used])
    return numbers, used


def _count_on(elapsed: np.ndarray, period: float, tolerance: float):
    """Whole periods from the anchor (``elapsed[0] == 0``) to each later pulse, counted from
    the previous accepted pulse, and which pulses are accepted."""
    numbers = np.zeros(elapsed.size)
    used = np.zeros(elapsed.size, dtype=bool)
    used[0] = True
    last_time, last_number = 0.0, 0.0
    for i in range(1, elapsed.size):
        whole = round((elapsed[i] - last_time) / period)
        numbers[i] = last_number + whole
        if whole > 0 and abs(elapsed[i] - last_time - whole * period) <= tolerance:
            used[i] = True
            last_time, last_number = elapsed[i], numbers[i]
    return numbers, used


def _placement_score(numbers: np.ndarray, used: np.ndarray) -> int:
    """Pulses on the clock less the clock's periods without one."""
    placed = int(used.sum())
    span = int(numbers[used].max() - numbers[used].min()) + 1
    return placed - (span - placed)


def _one_per_period(numbers: np.ndarray, distance: np.ndarray, candidate: np.ndarray):
    """Of the candidate pulses, the one nearest the clock in each period."""
    used = np.zeros(numbers.size, dtype=bool)
    order = np.flatnonzero(candidate)
    best: dict[float, int] = {}
    for i in order:
        j = best.get(numbers[i])
        if j is None or distance[i] < distance[j]:
            best[numbers[i]] = i
    used[list(best.values())] = True
    return used


def _line(numbers: np.ndarray, pulses: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """Least-squares t0 + n T through the pulses: (t0, T, standard error of T, residuals)."""
    design = np.column_stack([np.ones(numbers.size), numbers])
    (t0, period), *_ = np.linalg.lstsq(design, pulses, rcond=None)
    residual = pulses - (t0 + period * numbers)
    spread = float(np.sum((numbers - numbers.mean()) ** 2))
    se = _pulse_jitter(residual) / math.sqrt(spread) if spread > 0 else 0.0
    return float(t0), float(period), se, residual


def _pulse_jitter(residual: np.ndarray) -> float:
    """Standard deviation of a pulse about the clock (a line has 2 parameters); at least the
    quantisation to the sample grid, the least jitter a pulse has."""
    dof = residual.size - 2
    if dof <= 0:
        return 1.0 / math.sqrt(12.0)
    return max(math.sqrt(float(residual @ residual) / dof), 1.0 / math.sqrt(12.0))


def _check_rate(fs_hz: float) -> None:
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz = {fs_hz!r}: the sample rate must be > 0")


def _check_frequency(frequency_hz: float) -> None:
    if not (math.isfinite(frequency_hz) and frequency_hz > 0):
        raise ValueError(f"frequency_hz = {frequency_hz!r}: the drive frequency must be > 0")
