"""Make a measured angle fit for identification: bad samples, noise level, release, rest, velocity.

Real records start before the pendulum is let go, end long after it has stopped,
carry an unknown sensor zero and the odd glitch.  Each step here is detected from
the data alone and reported, so that the fits can state what they excluded.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.ndimage import maximum_filter1d, median_filter
from scipy.signal import find_peaks

from analysis.dynamics.lines import FALSE_ALARM
from analysis.identify.result import IdentificationError

SPIKE_THRESHOLD = 10.0  # robust standard deviations of the second difference
STILL_THRESHOLD = 6.0  # noise standard deviations within which the angle counts as held still
MIN_HELD_SAMPLES = 10
MAX_SPIKE_FRACTION = 0.002
MIN_SAMPLES_PER_PERIOD = 8
REST_FRACTION = 0.02  # oscillation below this fraction of the initial swing (and the noise) = rest
# Heavy tails: beyond 5 sigma a Gaussian puts 5.7e-7 of its samples; heavy tails need
# significantly more, carrying at least this share of the squared detail (least squares
# then spends that much of its attention on a few samples).
OUTLIER_SIGMA = 5.0
OUTLIER_SHARE = 0.01
GAUSSIAN_BEYOND = float(2.0 * stats.norm.sf(OUTLIER_SIGMA))  # two-sided, 5.7e-7
# A converter step below this fraction of the detail's spread moves its MAD by under 1 %
# (half a step at most): finer lattices need no correction.
LATTICE_FINE = 50.0


@dataclass(frozen=True)
class PreparedSignal:
    """The part of a record used by a fit, with what was removed and why."""

    time_s: np.ndarray  # time since the start of the used segment
    angle_rad: np.ndarray  # NaN where a sample was excluded
    valid: np.ndarray  # bool mask of usable samples
    start_index: int  # index in the original record of the first used sample
    stop_index: int  # one past the last used sample
    trim_start_s: float  # time removed at the start (before release)
    trim_end_s: float  # time removed at the end (pendulum at rest)
    n_nonfinite: int
    n_spikes: int
    noise_rad: float  # white-noise level estimated from second differences
    quantum_rad: float  # smallest nonzero step between samples (sensor resolution)
    notes: tuple[str, ...] = ()

    @property
    def n_excluded(self) -> int:
        """Samples inside the segment that the fit does not use."""
        return int(self.valid.size - np.count_nonzero(self.valid))


def sample_detail(values: np.ndarray) -> np.ndarray:
    """Second differences minus their running median: the smooth signal's curvature removed,
    the noise left (its standard deviation sqrt(6) times the noise's)."""
    d2 = np.diff(values, 2)
    return d2 - median_filter(d2, size=9, mode="nearest")


def _detail_scale(detail: np.ndarray) -> tuple[float, float]:
    """Robust spread of the detail and the sensor step it shows (0 for unquantised data).

    A quantised sensor makes most details 0 and the rest whole steps; the typical
    nonzero detail is then one step, which the MAD (often 0) does not see.
    """
    mad = float(np.median(np.abs(detail - np.median(detail))))
    nonzero = np.abs(detail[detail != 0])
    step = float(np.median(nonzero)) if nonzero.size else 0.0
    return 1.4826 * mad, step


def noise_and_quantum(angle: np.ndarray) -> tuple[float, float]:
    """White-noise level (robust, from second differences) and the sensor's typical step."""
    finite = angle[np.isfinite(angle)]
    if finite.size < 12:
        steps = np.abs(np.diff(finite))
        quantum = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
        return max(quantum, 1e-12), quantum
    spread, step = _detail_scale(sample_detail(finite))
    # The second difference of a white sequence has variance 6 sigma^2; a quantised signal
    # has noise of at least step / sqrt(12).
    quantum = step if spread == 0 else min(step, spread)
    noise = max(spread / math.sqrt(6.0), quantum / math.sqrt(12.0), 1e-12)
    return noise, quantum


@dataclass(frozen=True)
class TailSpikes:
    """Spikes of a noise-dominated detail sequence beyond OUTLIER_SIGMA robust standard
    deviations, against the count Gaussian noise puts there: of both signs (``side`` 0),
    or of one (``side`` -1 or +1, against half that count and half the share)."""

    count: int  # spikes beyond OUTLIER_SIGMA, each counted once (largest beside its neighbours)
    expected: float  # the count Gaussian noise puts there
    share: float  # of the detail's sum of squares, carried by the samples beyond
    samples: int  # length of the detail
    where: np.ndarray  # the spikes' indices in the detail
    side: int = 0

    @property
    def heavy(self) -> bool:
        """Significantly more spikes than a Gaussian gives (Poisson, p < FALSE_ALARM),
        carrying at least OUTLIER_SHARE of the squares (half of it on one side)."""
        needed = OUTLIER_SHARE if self.side == 0 else 0.5 * OUTLIER_SHARE
        return self.count > 0 and self.share >= needed \
            and float(stats.poisson.sf(self.count - 1, self.expected)) < FALSE_ALARM

    @property
    def fraction(self) -> float:
        """Spikes per sample of the detail."""
        return self.count / self.samples


def tail_spikes(detail: np.ndarray, *, scale: float | None = None,
                side: int = 0) -> TailSpikes | None:
    """The spikes of ``detail`` (a residual's or a record's sample-to-sample detail, smooth
    structure gone) beyond OUTLIER_SIGMA robust standard deviations from its median, or None
    when there is no spread to judge against.

    ``scale`` is that standard deviation when the caller knows it better than the plain
    MAD does (a quantised record's, :func:`lattice_spread`); ``side`` -1 or +1 counts only
    the spikes of that sign.  A spike of height h makes details of -h/2 (or h) beside it:
    only the largest of three neighbours counts, so each spike counts once (the count of
    all samples beyond is the Poisson test's upper bound, GAUSSIAN_BEYOND a sample)."""
    centre = float(np.median(detail))
    if scale is None:
        scale = 1.4826 * float(np.median(np.abs(detail - centre)))
    if not scale > 0:
        return None
    size = np.abs(detail - centre)
    beyond = size > OUTLIER_SIGMA * scale
    if side:
        beyond &= np.sign(detail - centre) == side
    largest = beyond & (size >= maximum_filter1d(size, 3, mode="nearest"))
    squares = (detail - centre) ** 2
    return TailSpikes(
        count=int(np.count_nonzero(largest)),
        expected=GAUSSIAN_BEYOND * detail.size * (0.5 if side else 1.0),
        share=float(squares[beyond].sum() / squares.sum()), samples=int(detail.size),
        where=np.flatnonzero(largest), side=side,
    )


def lattice_spread(values: np.ndarray, step: float) -> float:
    """Robust standard deviation (1.4826 MAD) of values on a lattice of ``step``, each
    lattice value's share spread evenly over its cell.  The plain MAD of whole steps is
    off by up to half a step: 30 % of the detail's MAD when the noise is about one step
    (a 12-bit converter's pi / 4096 = 7.7e-4 rad against the rig's 3e-4 to 2e-3 rad of
    noise): with it, 4 of 24 clean records on converters of 0.5-2 noise sigmas a step
    looked heavy-tailed."""
    centre = step * round(float(np.median(values)) / step)
    # cells past the median's are counted, not placed (the estimate reads the histogram up
    # to the median's cell only): a value far out on a fine lattice (a sweep step's jump on
    # float32's 4e-9 rad) made 2.5e13 cells, an allocation of 183 TiB
    distance = np.abs(values - centre) / step
    far = 2.0 * math.ceil(float(np.median(distance))) + 2.0
    cells = np.rint(np.minimum(distance, far)).astype(np.int64)
    share = np.bincount(cells) / cells.size
    below = np.cumsum(share) - share  # share of the cells nearer the centre
    k = int(np.searchsorted(np.cumsum(share), 0.5))
    if k == 0:  # the centre's cell, folded: its half-width holds all its share
        return 1.4826 * 0.5 * step * 0.5 / share[0]
    return 1.4826 * step * (k - 0.5 + (0.5 - below[k]) / share[k])


@dataclass(frozen=True)
class RecordTails:
    """A record's noise tails, judged from its raw detail before any fit: its spikes of
    each sign.  Noise is symmetric; an impact only ever slows the swing towards the
    barrier, and at low noise the detail of a fast one reaches 5 sigmas (reference
    records: 14 such in 20 s at 5.6e-4 rad of noise, 10 Hz), all of one sign: the noise
    is heavy-tailed when both signs are."""

    negative: TailSpikes
    positive: TailSpikes

    @property
    def heavy(self) -> bool:
        """Both signs' spikes significantly more than a Gaussian gives."""
        return self.negative.heavy and self.positive.heavy

    @property
    def count(self) -> int:
        """Spikes of both signs."""
        return self.negative.count + self.positive.count

    @property
    def expected(self) -> float:
        """The count Gaussian noise gives."""
        return self.negative.expected + self.positive.expected

    @property
    def share(self) -> float:
        """Share of the detail's sum of squares beyond OUTLIER_SIGMA."""
        return self.negative.share + self.positive.share


def _record_detail(finite: np.ndarray) -> tuple[np.ndarray, float]:
    """A raw record's detail (second differences less their running median: sampled fast,
    the motion's curvature is the running median's and the rest is noise) and its robust
    spread, the lattice's on a quantised record (:func:`lattice_spread`)."""
    detail = sample_detail(finite)
    levels = np.unique(finite)
    step = float(np.min(np.diff(levels))) if levels.size > 1 else 0.0
    spread = 1.4826 * float(np.median(np.abs(detail - np.median(detail))))
    if LATTICE_FINE * step > spread:
        spread = lattice_spread(detail, step)
    return detail, spread


def record_tails(angle: np.ndarray) -> RecordTails | None:
    """The noise tails of a raw record (NaN where excluded), from its detail, or None when
    too short or noiseless."""
    finite = angle[np.isfinite(angle)]
    if finite.size < 16:
        return None
    detail, spread = _record_detail(finite)
    sides = [tail_spikes(detail, scale=spread, side=side) for side in (-1, 1)]
    if sides[0] is None or sides[1] is None:
        return None
    return RecordTails(*sides)


def find_bad_samples(angle: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Mask of usable samples, with the counts of non-finite samples and of isolated spikes."""
    finite = np.isfinite(angle)
    valid = finite.copy()
    index = np.flatnonzero(finite)
    values = angle[index]
    n_spikes = 0
    if values.size >= 16:
        detail = sample_detail(values)
        spread, step = _detail_scale(detail)
        scale = max(spread, step, 1e-12)
        # A spike of height s at sample i gives a second difference -2s at i and +s beside it.
        strength = np.abs(detail) / scale
        candidates = np.flatnonzero(strength > SPIKE_THRESHOLD)
        spikes = [
            c for c in candidates
            if strength[c] >= strength[max(c - 1, 0):min(c + 2, strength.size)].max()
        ]
        # Glitches are rare; when many samples look like one, the noise itself is heavy
        # tailed (timing jitter, say) and cutting its tail would bias nothing but the report.
        if len(spikes) <= MAX_SPIKE_FRACTION * values.size:
            valid[index[np.asarray(spikes, dtype=np.int64) + 1]] = False
            n_spikes = len(spikes)
    return valid, int(np.count_nonzero(~finite)), n_spikes


def centre_estimate(angle: np.ndarray) -> float:
    """Rough rest angle of an oscillating signal: median of the midpoints of its swings."""
    clean = angle[np.isfinite(angle)]
    if clean.size < 3:
        raise IdentificationError("too few finite samples to locate the rest angle")
    low, high = np.percentile(clean, [1, 99])
    rough = 0.5 * (low + high)
    crossings = side_crossings(clean - rough)
    if crossings.size < 3:
        return float(np.median(clean))
    midpoints = []
    for a, b in itertools.pairwise(crossings):
        segment = clean[a:b + 1]
        midpoints.append(segment.max() if segment.mean() > rough else segment.min())
    extremes = np.asarray(midpoints)
    return float(np.median(0.5 * (extremes[:-1] + extremes[1:])))


def side_crossings(centred: np.ndarray, hysteresis: float | None = None) -> np.ndarray:
    """Indices where the signal changes side, counting only full passages across +-hysteresis."""
    if hysteresis is None:
        hysteresis = 3.0 * noise_and_quantum(centred)[0]
    state = np.zeros(centred.size, dtype=np.int8)
    state[centred > hysteresis] = 1
    state[centred < -hysteresis] = -1
    known = np.flatnonzero(state)
    if known.size < 2:
        return np.zeros(0, dtype=np.int64)
    sides = state[known]
    change = np.flatnonzero(sides[1:] != sides[:-1])
    return known[change + 1]


def turning_points(
    angle: np.ndarray, centre: float, noise: float, min_distance: int
) -> np.ndarray:
    """Indices of the alternating extremes of a noisy oscillation (prominence above the noise)."""
    filled = _fill_invalid(angle)
    prominence = 10.0 * noise
    peaks, _ = find_peaks(filled - centre, prominence=prominence, distance=min_distance)
    troughs, _ = find_peaks(centre - filled, prominence=prominence, distance=min_distance)
    return np.sort(np.concatenate([peaks, troughs]))


def _fill_invalid(angle: np.ndarray) -> np.ndarray:
    good = np.isfinite(angle)
    if good.all():
        return angle
    idx = np.arange(angle.size)
    return np.interp(idx, idx[good], angle[good])


def prepare(time_s: np.ndarray, angle_rad: np.ndarray, *, detect_release: bool = True,
            trim_rest: bool = True) -> PreparedSignal:
    """Exclude bad samples, trim before the release and after the pendulum comes to rest."""
    if time_s.size < 16:
        raise IdentificationError(f"record too short: {time_s.size} samples, need at least 16")
    valid, n_nonfinite, n_spikes = find_bad_samples(angle_rad)
    if np.count_nonzero(valid) < 16:
        raise IdentificationError(
            f"only {np.count_nonzero(valid)} usable samples ({n_nonfinite} not finite)"
        )
    angle = np.where(valid, angle_rad, np.nan)
    filled = _fill_invalid(angle)
    _require_resolved_oscillation(time_s, filled)
    noise, quantum = noise_and_quantum(angle)
    notes: list[str] = []
    start = 0
    if detect_release:
        start, note = _release_index(filled, noise, quantum)
        if note:
            notes.append(note)
    stop = angle.size
    if trim_rest:
        stop = _rest_index(filled, start, noise, quantum)
    if stop - start < 16:
        raise IdentificationError(
            f"no usable motion: only {stop - start} samples between release and rest"
        )
    t0 = time_s[start]
    if stop < angle.size:
        notes.append(
            f"the pendulum is at rest from t = {time_s[stop] - time_s[0]:.4g} s on; "
            f"the last {time_s[-1] - time_s[stop - 1]:.4g} s are not fitted"
        )
    return PreparedSignal(
        time_s=time_s[start:stop] - t0,
        angle_rad=angle[start:stop],
        valid=valid[start:stop],
        start_index=start,
        stop_index=stop,
        trim_start_s=float(t0 - time_s[0]),
        trim_end_s=float(time_s[-1] - time_s[stop - 1]),
        n_nonfinite=n_nonfinite,
        n_spikes=n_spikes,
        noise_rad=noise,
        quantum_rad=quantum,
        notes=tuple(notes),
    )


def _require_resolved_oscillation(time_s: np.ndarray, filled: np.ndarray) -> None:
    """Refuse noise-only and undersampled records before any step trusts sample-to-sample change.

    A sampled oscillation is smooth from one sample to the next (lag-1 correlation
    cos(2 pi / n) for n samples per period); if it is not, the spectrum tells a sharp
    line sampled too sparsely from noise with no line at all.
    """
    centred = filled - np.median(filled)
    if not np.any(centred):
        raise IdentificationError("no oscillation: the angle is constant")
    rho1 = float(np.dot(centred[1:], centred[:-1]) / np.dot(centred, centred))
    if rho1 >= math.cos(2.0 * math.pi / MIN_SAMPLES_PER_PERIOD):
        return
    power = np.abs(np.fft.rfft(centred * np.hanning(centred.size))) ** 2
    dt = (time_s[-1] - time_s[0]) / (time_s.size - 1)
    peak = int(np.argmax(power[1:])) + 1
    if power[peak] > 50.0 * np.median(power[1:]):
        frequency = peak / (centred.size * dt)
        raise IdentificationError(
            f"too few samples per period: the oscillation at about {frequency:.3g} Hz (or an "
            f"alias) has {1.0 / (frequency * dt):.2g} samples per period at "
            f"{1.0 / dt:.3g} Hz; need at least {MIN_SAMPLES_PER_PERIOD}"
        )
    raise IdentificationError(
        "no oscillation: the angle changes from sample to sample like noise, with no "
        "spectral line"
    )


def _release_index(filled: np.ndarray, noise: float, quantum: float) -> tuple[int, str]:
    """First sample of free motion: the end of a held-still start, else the first turning point.

    Before the release the angle is either held still, or still being moved by hand
    towards the release angle; in a free decay no swing is larger than the first, so
    motion away from the centre beyond the starting angle is pre-release.
    """
    band = max(STILL_THRESHOLD * noise, 2.0 * quantum)
    reference = np.median(filled[:5])
    moved = np.flatnonzero(np.abs(filled - reference) > band)
    if moved.size == 0:
        raise IdentificationError("no oscillation: the angle never leaves its starting value")
    held = int(moved[0])
    centre = centre_estimate(filled[held:])
    period_guess = _rough_period_samples(filled[held:] - centre)
    # A pendulum let go from rest at t = 0 also stays inside the band for a moment; a hold
    # is only recognised when it lasts a good fraction of a period.
    if held >= max(MIN_HELD_SAMPLES, period_guess // 4):
        return held - 1, f"held still until release at sample {held - 1}"
    extremes = turning_points(filled, centre, noise, max(2, period_guess // 4))
    if extremes.size == 0:
        return 0, ""
    first = int(extremes[0])
    if abs(filled[first] - centre) > abs(filled[0] - centre) + band:
        return first, f"moving away from rest until the first turning point at sample {first}"
    return 0, ""


def _rough_period_samples(centred: np.ndarray) -> int:
    crossings = side_crossings(centred)
    if crossings.size < 3:
        return max(4, centred.size // 2)
    return int(max(4, 2 * np.median(np.diff(crossings))))


def _rest_index(filled: np.ndarray, start: int, noise: float, quantum: float) -> int:
    """One past the last sample of visible oscillation (the record's end if it never stops)."""
    segment = filled[start:]
    centre = centre_estimate(segment)
    period = _rough_period_samples(segment - centre)
    if segment.size < 3 * period:
        return filled.size
    initial = float(np.max(np.abs(segment[:period] - centre)))
    level = max(8.0 * noise, 3.0 * quantum, REST_FRACTION * initial)
    n_windows = segment.size // period
    windows = segment[: n_windows * period].reshape(n_windows, period)
    swing = windows.max(axis=1) - windows.min(axis=1)
    moving = np.flatnonzero(swing > 2.0 * level)
    if moving.size == 0:
        raise IdentificationError("no oscillation above the noise level after the release")
    last = int(moving[-1])
    if last >= n_windows - 2:
        return filled.size
    return start + (last + 1) * period

