"""The regime of a measured forced record, judged from its strobe points aware of its noise.

Period k when points k drive periods apart agree within the noise, or approach such an
orbit as a decaying transient does; chaotic only when no period is found and both the
0-1 test and the divergence of neighbours from the data say so (both made to see chaos
in bands, :mod:`analysis.dynamics.strobe_chaos`); quasi-periodic when both say regular;
undetermined when they disagree.  The strobe points come from
:mod:`analysis.dynamics.strobe`, locked to the tach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.dynamics.lines import (
    HARMONIC_GUARD_BINS,
    MERGE_BINS,
    find_lines,
    line_threshold,
    local_floor,
    periodic_part,
    periodogram,
)
from analysis.dynamics.regime import Regime, harmonic_content, harmonic_text
from analysis.dynamics.spectrum import amplitude_spectrum
from analysis.dynamics.strobe import StrobeSamples, strobe_record
from analysis.dynamics.strobe_chaos import (
    bands_from_recurrence,
    neighbour_divergence,
    zero_one_about_bands,
)

# Two strobe points agree when their differences, in units of the noise of a difference,
# have an RMS over the phases of at most AGREEMENT_RMS.  Under noise alone a pair exceeds
# it with probability ~1e-12 for 8 phases, and still only ~2 % of pairs do when the sample
# noise is twice the one stated; a wrong period leaves differences of the orbit's size.
AGREEMENT_RMS = 3.0
# A period holds when at most this fraction of the settled pairs disagree (a glitch, a
# pulse the clock could not place), so one bad sample does not hide it ...
MAX_DISAGREEING_FRACTION = 0.05
# ... and the median pair differs by at most this (noise alone: ~0.96 for 8 phases): a
# difference of the size of the noise in every pair is a slow orbit, not noise.
MAX_MEDIAN_RMS = 1.5
MIN_PAIRS = 8  # and at least 2 k pairs: each point of a period-k orbit met twice
MAX_TRANSIENT_FRACTION = 0.5  # the settled part is at least the record's second half
# Points k periods apart of a settling orbit must draw together at least this much (RMS,
# noise removed) from the first to the second half of the settled part.
SETTLING_SHRINK = 2.0
# Each orbit point in at least this many equations of the settling model: with fewer, its
# own constant leaves so much freedom that a nonlinear transient passes for a linear one.
SETTLING_EQUATIONS_PER_POINT = 5
TRANSIENT_STEPS = 20  # transient lengths tried: the record's first half in this many steps
CHAOS_K = 0.5  # 0-1 test K above this: chaotic by the 0-1 test
MIN_ZERO_ONE_SAMPLES = 50  # the 0-1 test's least
# An added line (a hum) is steady: its fits to the two halves of the record differ by at
# most this many standard errors plus this share of its amplitude (a free oscillation
# decays by far more over a record; a sensor's hum wanders by far less).
STEADY_Z = 4.0
STEADY_RELATIVE = 0.25
SIDEBAND_BINS = 2  # bins either side of an expected sideband searched for it
MIN_LINE_SAMPLES = 1024  # fewer valid samples: no added line is looked for
# A line below this rms, in noise units, changes no agreement of strobe points (the
# residual reading's least structure that counts, analysis.discrepancy MIN_STRUCTURE)
MIN_LINE_RMS = 0.2


def judge_regime(
    strobe: StrobeSamples,
    noise_rad: float,
    *,
    theta: np.ndarray | None = None,
    max_period: int = 32,
    seed: int = 0,
) -> Regime:
    """Judge the regime of a forced record from its strobe points and its sample noise.

    The tolerance follows from ``noise_rad``, the standard deviation of the record's
    white sample noise (quantisation included): a strobe point's noise is that times
    its local fit's noise gain, combined with the strobe clock's timing uncertainty
    times the angle's slope; a difference of two points has the root sum of squares of
    theirs, and two points agree when their differences, in units of that noise, have
    an RMS over the phases of at most AGREEMENT_RMS (``tolerance_rad`` in the evidence
    is that bound for typical points).  Period k is the smallest k <=
    ``max_period`` for which, from some period n0 in the first half of the record on
    (n0 periods of transient),

    * points k periods apart agree (at most 5 % of at least max(2k, 8) pairs disagree,
      the median pair within MAX_MEDIAN_RMS) and every point agrees with the mean of
      its orbit point's visits;
    * or, failing that, the points approach a period-k orbit as a decaying transient
      does: p[n+2k] = a p[n+k] + b p[n] + c (c per orbit point: the linearised k-period
      map of the pendulum's two-dimensional state) holds within the same tolerance,
      the roots of z^2 = a z + b lie inside the unit circle, and points k periods apart
      draw together at least SETTLING_SHRINK-fold from the first half to the second,
      in the data and in the fitted roots.  The orbit approached may repeat after a
      divisor of k, which is then the period.

    Without a period the recurrence still shows bands when every multiple of some lag
    m brings the points far closer than typical (chaos about a period-m orbit).
    Chaotic only when the 0-1 test on the phase-0 points less their band means gives
    K > CHAOS_K and nearest neighbours in the same band separate from the noise floor
    at least twofold (:mod:`analysis.dynamics.strobe_chaos`); quasi-periodic (or a
    period beyond the ones tested) when both say regular; undetermined when they
    disagree or the record is too short for them.  ``theta`` (the record the strobe
    came from) adds the sub- and superharmonics of its settled part.  The evidence
    holds the clock, the tolerance, 'recurrence' (median RMS difference of points
    k = 1, 2, ... periods apart over the second half, in noise units),
    'transient_periods', 'transient_s', 'settling', 'band_period', 'K',
    'lyapunov_per_period' (biased low when the noise floor hides the start of the
    divergence), 'divergence_rise' (log of the fold).
    """
    if not (math.isfinite(noise_rad) and noise_rad > 0):
        raise ValueError(f"noise_rad = {noise_rad!r}: the sample noise must be > 0")
    if max_period < 1:
        raise ValueError(f"max_period = {max_period}: must be at least 1")
    points = strobe.points
    if len(strobe) < MIN_PAIRS + 1:
        raise ValueError(
            f"{len(strobe)} drive periods in the record: need at least {MIN_PAIRS + 1} "
            "to judge its regime"
        )
    sigma = np.hypot(noise_rad * strobe.noise_gain, strobe.timing_noise_rad)
    evidence: dict[str, Any] = {
        "clock": strobe.clock.summary(),
        "periods_in_record": len(strobe),
        "phases_per_period": strobe.phases_per_period,
        "noise_rad": float(noise_rad),
        "tolerance_rad": float(AGREEMENT_RMS * np.sqrt(2.0) * np.nanmedian(sigma)),
    }
    recurrence = []
    for k in range(1, max_period + 1):
        if len(strobe) - k < _min_pairs(k):
            break
        recurs = _recurrence(points, sigma, k)
        recurrence.append(recurs.median_rms)
        evidence["recurrence"] = np.array(recurrence)
        if recurs.start is not None:
            return _periodic(strobe, recurs.period, recurs.start, None, evidence, theta)
        settling = _settling(points, sigma, k)
        if settling is not None:
            return _periodic(strobe, settling.period, settling.start, settling, evidence, theta)
    evidence["max_period_tested"] = len(recurrence)
    return _not_periodic(strobe, sigma, evidence, theta, seed)


def judge_record_regime(
    theta: np.ndarray,
    fs_hz: float,
    noise_rad: float,
    *,
    tach_indices: np.ndarray | None = None,
    frequency_hz: float | None = None,
    phase_rad: float = 0.0,
    max_period: int = 32,
) -> tuple[Regime, StrobeSamples]:
    """Strobe a forced record (on its tach, else on the stated drive) and judge its regime.

    Lines the pendulum cannot have made (:func:`additive_lines`: a hum in the sensor) are
    taken out first: strobed, such a line aliases into a pattern that repeats after
    some k periods and would pass for a period-k orbit (or hides the period the record
    has).  When the record without them is periodic they are in the evidence as
    'additive_lines'; when it is not, the record is judged as it came.  Returns the
    regime and the strobe points of the record judged (the settled section is
    ``strobe.section[regime.evidence['transient_periods']:]`` for a periodic record).
    """
    def judged(record: np.ndarray) -> tuple[Regime, StrobeSamples]:
        strobe = strobe_record(record, fs_hz, tach_indices=tach_indices,
                               frequency_hz=frequency_hz, phase_rad=phase_rad)
        return judge_regime(strobe, noise_rad, theta=record, max_period=max_period), strobe

    theta = np.asarray(theta, dtype=float)
    as_recorded = judged(theta)
    drive_hz = as_recorded[1].clock.frequency_hz
    lines = [line for line in additive_lines(theta, fs_hz, drive_hz)
             if line.amplitude_rad / math.sqrt(2.0) >= MIN_LINE_RMS * noise_rad]
    t = np.arange(theta.size) / fs_hz
    guard_hz = HARMONIC_GUARD_BINS * fs_hz / theta.size
    while lines:
        regime, strobe = judged(theta - sum(line.at(t) for line in lines))
        if regime.kind != "periodic":
            # a line matters to the judgement when it fakes or hides a period; in a motion
            # that has none even without it, it may be the motion's own (chaos mixes its
            # sidebands into a floor they do not stand out of)
            return as_recorded
        # a line at a multiple of f / k belongs to the period-k orbit found
        base_hz = drive_hz / regime.period
        kept = [line for line in lines
                if abs(math.remainder(line.frequency_hz, base_hz)) > guard_hz]
        if len(kept) == len(lines):
            break
        lines = kept
    else:
        return as_recorded
    evidence = dict(regime.evidence)
    evidence["additive_lines"] = [line.as_json() for line in lines]
    taken = ", ".join(f"{line.frequency_hz:.4g} Hz" for line in lines)
    label = f"{regime.label}; a line at {taken} taken out (no sidebands: not the pendulum's)"
    return Regime(regime.kind, regime.period, label, MappingProxyType(evidence)), strobe


@dataclass(frozen=True)
class AdditiveLine:
    """A steady tone added to the record, not made by the pendulum (see additive_lines)."""

    frequency_hz: float
    amplitude_rad: float
    phase_rad: float  # of the cosine at sample 0

    def at(self, t_s: np.ndarray) -> np.ndarray:
        """The line's value at times ``t_s`` [s] from the record's first sample."""
        return self.amplitude_rad * np.cos(2.0 * math.pi * self.frequency_hz * t_s
                                           + self.phase_rad)

    def as_json(self) -> dict[str, float]:
        return {q.frequency_hz: self.frequency_hz, "amplitude_rad": self.amplitude_rad}


def additive_lines(theta: np.ndarray, fs_hz: float, drive_hz: float) -> tuple[AdditiveLine, ...]:
    """Lines above the drive frequency that the pendulum cannot have made.

    Whatever the pendulum does at a frequency off the drive's harmonics, it does through
    the impacts and its own nonlinearity, which mix it with the drive: its line has
    sidebands at f_line +- f and +- 2 f.  A sensor's hum has none, and it is steady: the
    same amplitude and phase in either half of the record.  A line found off the drive's
    harmonics (:func:`analysis.dynamics.lines.find_lines`) counts as added when it lies
    above the drive frequency, no sideband stands above the floor, it is no sideband or
    second harmonic of another line found, and its halves agree within STEADY_Z standard
    errors plus STEADY_RELATIVE of its size.
    A torus or a subharmonic orbit has sidebands; a decaying free oscillation is not
    steady; below the drive frequency the pendulum's own linear response is left alone.
    """
    x = np.asarray(theta, dtype=float)
    ok = np.isfinite(x)
    if x.size < 2 or np.count_nonzero(ok) < MIN_LINE_SAMPLES:
        return ()
    t = np.arange(x.size) / fs_hz
    filled = np.where(ok, x, 0.0)
    found = find_lines(t, filled, ok, drive_hz)
    if not found:
        return ()
    residual = np.where(ok, filled - periodic_part(t, filled, ok, drive_hz), 0.0)
    power = periodogram(np.where(ok, residual - residual[ok].mean(), 0.0), ok)
    floor = local_floor(power)
    df = fs_hz / x.size
    lines = []
    for frequency, _ in found:
        if frequency <= drive_hz:
            continue
        sidebands = [frequency + j * drive_hz for j in (-2, -1, 1, 2)]
        sidebands = [s for s in sidebands if 0.0 < s < fs_hz / 2.0 - MERGE_BINS * df]
        mixed = [m * g + j * drive_hz for g, _ in found if g != frequency
                 for m in (1, 2) for j in range(-2, 3)]
        if any(abs(frequency - c) <= MERGE_BINS * df for c in mixed):
            continue  # a sideband or a harmonic of another line: part of one motion
        if _sideband_shows(power, floor, sidebands, df):
            continue
        line = _steady_line(t, residual, ok, frequency, float(floor[round(frequency / df)]))
        if line is not None:
            lines.append(line)
    return tuple(lines)


def _sideband_shows(power: np.ndarray, floor: np.ndarray, sidebands: list[float],
                    df: float) -> bool:
    """Whether any bin within SIDEBAND_BINS of an expected sideband passes the line
    threshold for the bins so searched."""
    bins = [np.arange(round(s / df) - SIDEBAND_BINS, round(s / df) + SIDEBAND_BINS + 1)
            for s in sidebands]
    if not bins:
        return False
    searched = np.clip(np.concatenate(bins), 0, power.size - 1)
    return bool(np.any(power[searched] / floor[searched] > line_threshold(searched.size)))


def _steady_line(
    t: np.ndarray, residual: np.ndarray, ok: np.ndarray, frequency_hz: float,
    floor_power: float,
) -> AdditiveLine | None:
    """The line fitted over the whole record when its fits to each half agree, else None.

    A half's cosine and sine coefficients each have the standard error
    sqrt(2 floor / samples), ``floor_power`` being the local noise floor at the line's
    frequency (the power of white noise of that level): the record's noise near the line,
    not the whole residual's, which a chaotic motion's broadband swells."""
    def fit(mask: np.ndarray) -> tuple[complex, float]:
        phase = 2.0 * math.pi * frequency_hz * t[mask]
        basis = np.column_stack([np.ones(phase.size), np.cos(phase), np.sin(phase)])
        coef, *_ = np.linalg.lstsq(basis, residual[mask], rcond=None)
        return complex(coef[1], -coef[2]), math.sqrt(2.0 * floor_power / phase.size)

    half = t.size // 2
    first, second = np.zeros_like(ok), np.zeros_like(ok)
    first[:half], second[half:] = ok[:half], ok[half:]
    (c1, s1), (c2, s2), (whole, _) = fit(first), fit(second), fit(ok)
    if abs(c1 - c2) > STEADY_Z * math.hypot(s1, s2) + STEADY_RELATIVE * abs(whole):
        return None
    return AdditiveLine(float(frequency_hz), abs(whole), float(np.angle(whole)))


@dataclass(frozen=True)
class _Recurrence:
    start: int | None  # first settled period, None when points k apart do not agree
    period: int  # k, or the divisor of k after which the settled orbit repeats
    median_rms: float  # median RMS difference over the second half, in noise units


@dataclass(frozen=True)
class _Settling:
    start: int
    period: int  # of the orbit approached: k, or a divisor of k it repeats after
    decay_per_period: float
    # RMS difference of points k periods apart (noise removed), in the first and the second
    # half of the settled part
    difference_first_half_rad: float
    difference_second_half_rad: float


def _min_pairs(k: int) -> int:
    return max(2 * k, MIN_PAIRS)


def _min_settling_equations(k: int) -> int:
    return max(SETTLING_EQUATIONS_PER_POINT * k, MIN_PAIRS)


def _recurrence(points: np.ndarray, sigma: np.ndarray, k: int) -> _Recurrence:
    """Smallest start (within the first half) from which points k periods apart agree, and
    every point stays within the noise of the mean of its orbit point (its visits k, 2k,
    ... periods away: a slow drift, as of a torus near a k-period resonance, is no orbit)."""
    n = points.shape[0]
    rms = _rms_difference(points[k:], points[:-k], sigma[k:], sigma[:-k])
    valid = np.isfinite(rms)
    bad = valid & (rms > AGREEMENT_RMS)
    # pairs from each start on, counted from the end
    valid_after = np.cumsum(valid[::-1])[::-1]
    bad_after = np.cumsum(bad[::-1])[::-1]
    last_start = min(int(MAX_TRANSIENT_FRACTION * n), rms.size - 1)
    enough = valid_after[: last_start + 1] >= _min_pairs(k)
    agree = bad_after[: last_start + 1] <= MAX_DISAGREEING_FRACTION * valid_after[: last_start + 1]
    # the settled part begins settled: the glitches it may hold are not the transient's tail
    window = _min_pairs(k)
    bad_ahead = bad_after - np.concatenate([bad_after[window:], np.zeros(window, dtype=int)])
    agree &= bad_ahead[: last_start + 1] <= 1
    tail = rms[rms.size // 2 :]
    tail = tail[np.isfinite(tail)]
    median_rms = float(np.median(tail)) if tail.size else math.inf
    spacing = max(1, n // (2 * TRANSIENT_STEPS))
    tried = -spacing
    for start in np.flatnonzero(enough & agree):
        if start < tried + spacing:
            continue
        tried = start
        if np.median(rms[start:][valid[start:]]) > MAX_MEDIAN_RMS:
            continue
        orbit = _orbit_points(points[start:], sigma[start:], k)
        if orbit is not None:
            period = _orbit_period(orbit, float(np.nanmedian(sigma)), k)
            return _Recurrence(int(start), period, median_rms)
    return _Recurrence(None, k, median_rms)


def _orbit_points(points: np.ndarray, sigma: np.ndarray, k: int) -> np.ndarray | None:
    """The k orbit points (means of their visits) when every point lies within the noise of
    its mean, with the tolerance of pairs; else None."""
    finite = np.all(np.isfinite(points), axis=1)
    orbit_point = np.arange(points.shape[0])[finite] % k
    counts = np.bincount(orbit_point, minlength=k)
    if counts.min() < 2:
        return None
    membership = (orbit_point[:, None] == np.arange(k)[None, :]).astype(float)
    mean = (membership.T @ points[finite]) / counts[:, None]
    # a point's distance from a mean it is part of has variance sigma^2 (1 - 1/count)
    scale = sigma[finite] * np.sqrt(1.0 - 1.0 / counts[orbit_point])[:, None]
    rms = np.sqrt(np.mean(((points[finite] - mean[orbit_point]) / scale) ** 2, axis=1))
    holds = (
        np.count_nonzero(rms > AGREEMENT_RMS) <= MAX_DISAGREEING_FRACTION * rms.size
        and np.median(rms) <= MAX_MEDIAN_RMS
    )
    return mean if holds else None


def _rms_difference(p: np.ndarray, q: np.ndarray, sigma_p: np.ndarray, sigma_q: np.ndarray):
    """RMS over the phases of (p - q) in units of the noise of the difference, per point."""
    return np.sqrt(np.mean((p - q) ** 2 / (sigma_p**2 + sigma_q**2), axis=1))


def _settling(points: np.ndarray, sigma: np.ndarray, k: int) -> _Settling | None:
    """The first start from which the points approach a period-k orbit as a decaying
    transient does (see :func:`judge_regime`), or None."""
    n = points.shape[0]
    step = max(1, n // (2 * TRANSIENT_STEPS))
    for start in range(0, int(MAX_TRANSIENT_FRACTION * n) + 1, step):
        if n - start - 2 * k < _min_settling_equations(k):
            return None
        fit = _settling_from(points[start:], sigma[start:], k)
        if fit is not None:
            return _Settling(start, *fit)
    return None


def _settling_from(points: np.ndarray, sigma: np.ndarray, k: int):
    """(orbit period, decay per period, RMS difference of points k periods apart in the first
    and in the second half) when the linear settling model of period k fits ``points``
    within the noise and its transient decays, else None."""
    n, d = points.shape
    rows = np.arange(n - 2 * k)
    target, middle, early = points[rows + 2 * k], points[rows + k], points[rows]
    finite = np.all(np.isfinite(target) & np.isfinite(middle) & np.isfinite(early), axis=1)
    rows = rows[finite]
    if rows.size < _min_settling_equations(k):
        return None
    target, middle, early = target[finite], middle[finite], early[finite]
    orbit_point = rows % k
    membership = (orbit_point[:, None] == np.arange(k)[None, :]).astype(float)
    counts = membership.sum(axis=0)
    if counts.min() < 2:
        return None

    def centred(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mean = (membership.T @ x) / counts[:, None]
        return x - mean[orbit_point], mean

    y, y_mean = centred(target)
    x1, x1_mean = centred(middle)
    x2, x2_mean = centred(early)
    # Least squares for (a, b), its normal matrix freed of the noise the regressors carry
    # (known: sigma, less what the class means take), which would pull a, b toward 0 and
    # make a persistent oscillation look like a decaying one.
    kept = (1.0 - 1.0 / counts[orbit_point])[:, None]
    normal = np.array([
        [np.sum(x1 * x1) - np.sum(kept * sigma[rows + k] ** 2), np.sum(x1 * x2)],
        [np.sum(x1 * x2), np.sum(x2 * x2) - np.sum(kept * sigma[rows] ** 2)],
    ])
    if np.linalg.eigvalsh(normal)[0] <= 0.0 or np.linalg.cond(normal) > 1e12:
        return None  # no transient above the noise to fit
    a, b = np.linalg.solve(normal, [np.sum(x1 * y), np.sum(x2 * y)])
    decay = _largest_root(a, b) ** (1.0 / k)
    if not decay < 1.0 or decay ** (n / 2.0) > 1.0 / SETTLING_SHRINK:
        return None  # the model's own transient does not shrink over the record
    s_target = sigma[rows + 2 * k]
    s_middle, s_early = sigma[rows + k], sigma[rows]
    scale = np.sqrt(s_target**2 + (a * s_middle) ** 2 + (b * s_early) ** 2)
    rms = np.sqrt(np.mean(((y - a * x1 - b * x2) / scale) ** 2, axis=1))
    if (
        np.count_nonzero(rms > AGREEMENT_RMS) > MAX_DISAGREEING_FRACTION * rms.size
        or np.median(rms) > MAX_MEDIAN_RMS
    ):
        return None
    # A decaying transient shows in the data, not only in the fitted roots: points k periods
    # apart (whose difference needs no fitted orbit) must draw together.
    first, second = _difference_excess(points, sigma, k)
    if first < 3.0 * math.sqrt(2.0 / (d * (n // 2))) or first < SETTLING_SHRINK**2 * max(
        second, 0.0
    ):
        return None
    point_noise = float(np.nanmedian(sigma))
    orbit = (y_mean - a * x1_mean - b * x2_mean) / (1.0 - a - b)
    return (
        _orbit_period(orbit, point_noise, k),
        decay,
        point_noise * math.sqrt(2.0 * first),  # the noise of a difference is sqrt(2) a point's
        point_noise * math.sqrt(2.0 * max(second, 0.0)),
    )


def _difference_excess(points: np.ndarray, sigma: np.ndarray, k: int) -> tuple[float, float]:
    """Mean square of the differences of points k periods apart over the noise's, less 1
    (the transient's share), in the first and the second half of ``points``."""
    rms = _rms_difference(points[k:], points[:-k], sigma[k:], sigma[:-k])
    half = rms.size // 2
    return float(np.nanmean(rms[:half] ** 2)) - 1.0, float(np.nanmean(rms[half:] ** 2)) - 1.0


def _largest_root(a: float, b: float) -> float:
    """Largest modulus of the roots of z^2 = a z + b."""
    discriminant = a * a + 4.0 * b
    if discriminant < 0.0:
        return math.sqrt(-b)  # a complex pair, |z|^2 = -b
    return (abs(a) + math.sqrt(discriminant)) / 2.0


def _orbit_period(orbit: np.ndarray, sigma: float, k: int) -> int:
    """Smallest divisor p of k after which the orbit repeats as points p periods apart must.

    A transient whose phase turns by nearly a whole number of turns in k periods (k = 2p,
    or near a period doubling) spoils the comparison of points p periods apart more than
    of those k apart; the orbit its points scatter about still has period p.
    """
    for p in range(1, k):
        if k % p:
            continue
        rms = _rms_difference(orbit, np.roll(orbit, -p, axis=0), sigma, sigma)
        if np.all(rms <= AGREEMENT_RMS) and np.median(rms) <= MAX_MEDIAN_RMS:
            return p
    return k


def _periodic(
    strobe: StrobeSamples,
    k: int,
    transient: int,
    settling: _Settling | None,
    evidence: dict[str, Any],
    theta: np.ndarray | None,
) -> Regime:
    evidence["transient_periods"] = int(transient)
    evidence["transient_s"] = float(transient * strobe.clock.period_s)
    evidence["settled_periods"] = len(strobe) - int(transient)
    label = f"period-{k}"
    if settling is not None:
        evidence["settling"] = {
            "decay_per_period": settling.decay_per_period,
            "difference_first_half_rad": settling.difference_first_half_rad,
            "difference_second_half_rad": settling.difference_second_half_rad,
        }
        label += ", settling"
    harmonics = _record_harmonics(strobe, theta, transient)
    evidence.update(harmonics)
    label += harmonic_text(harmonics)
    return Regime("periodic", k, label, MappingProxyType(evidence))


def _not_periodic(
    strobe: StrobeSamples,
    sigma: np.ndarray,
    evidence: dict[str, Any],
    theta: np.ndarray | None,
    seed: int,
) -> Regime:
    tested = evidence["max_period_tested"]
    run = _longest_finite_run(strobe.points)
    evidence["chaos_tests_on_periods"] = [int(run.start), int(run.stop)]
    points = strobe.points[run]
    if points.shape[0] < MIN_ZERO_ONE_SAMPLES:
        label = (
            f"undetermined: no period up to {tested}, and {points.shape[0]} periods are too few "
            f"for the 0-1 test (needs {MIN_ZERO_ONE_SAMPLES})"
        )
        return Regime("undetermined", None, label, MappingProxyType(evidence))
    bands = bands_from_recurrence(evidence["recurrence"])
    evidence["band_period"] = bands.period
    k01 = zero_one_about_bands(points[:, 0], bands.skeleton_period, seed=seed)
    evidence["K"] = k01
    divergence = neighbour_divergence(points, sigma[run], band_period=bands.period)
    exponent = divergence.exponent_per_period
    evidence["lyapunov_per_period"] = exponent
    evidence["lyapunov_note"] = divergence.note
    evidence["divergence_rise"] = divergence.rise
    evidence.update(_record_harmonics(strobe, theta, 0))
    k_says = k01 > CHAOS_K
    lyapunov_says = divergence.diverges
    in_bands = f" in {bands.period} bands" if bands.period > 1 else ""
    k_text = f"0-1 test K = {k01:.2f}{' about the bands' if in_bands else ''}"
    lyapunov_text = (
        f"largest Lyapunov exponent {exponent:.3g} per period"
        if exponent is not None
        else f"no exponential divergence ({divergence.note})"
    )
    if k_says and lyapunov_says:
        label = f"chaotic{in_bands} (K = {k01:.2f}, lambda = {exponent:.3g} per period)"
        return Regime("chaotic", None, label, MappingProxyType(evidence))
    if not k_says and not lyapunov_says:
        label = f"quasi-periodic or period > {tested} ({k_text}; {lyapunov_text})"
        if evidence.get("incommensurate"):
            label += f", lines at {', '.join(evidence['incommensurate'])}"
        return Regime("quasi_periodic", None, label, MappingProxyType(evidence))
    verdicts = (
        f"{k_text} ({'chaotic' if k_says else 'regular'}) but {lyapunov_text} "
        f"({'chaotic' if lyapunov_says else 'regular'})"
    )
    label = f"undetermined: no period up to {tested}; {verdicts}"
    return Regime("undetermined", None, label, MappingProxyType(evidence))


def _longest_finite_run(points: np.ndarray) -> slice:
    finite = np.all(np.isfinite(points), axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    starts, stops = edges[0::2], edges[1::2]
    if starts.size == 0:
        return slice(0, 0)
    longest = int(np.argmax(stops - starts))
    return slice(int(starts[longest]), int(stops[longest]))


def _record_harmonics(
    strobe: StrobeSamples, theta: np.ndarray | None, transient_periods: int
) -> dict[str, Any]:
    """Sub- and superharmonics of the record's settled part ({} without a gap-free record)."""
    if theta is None:
        return {}
    settled = np.asarray(theta, dtype=float)[strobe.start_sample(transient_periods) :]
    if settled.size < 8 or not np.all(np.isfinite(settled)):
        return {}
    spectrum = amplitude_spectrum(
        settled, strobe.clock.fs_hz, drive_frequency_hz=strobe.clock.frequency_hz
    )
    return harmonic_content(spectrum)
