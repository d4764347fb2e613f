"""Chaos tests on the strobe points of a forced record that no period explains.

Chaos often lives in bands: the motion visits m regions in turn, as a period-m orbit
would, and wanders chaotically inside each.  The points' periodic skeleton then hides
the chaos from both tests: the 0-1 test reads a periodic signal plus a small chaotic
one as regular, and neighbours that stay inside a band never spread over the whole
attractor.  So the 0-1 test runs on the section less the mean of each band, and the
divergence of neighbours (followed within their band) is measured from the noise
floor, in units of the points' noise, not against the attractor's size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.dynamics.chaos01 import zero_one_test
from analysis.dynamics.lyapunov import scaling_region

# Points k periods apart that differ by at most this fraction of the typical recurrence
# (median over the lags tested) are in the same band: the motion returns near itself.
BAND_DIP_FRACTION = 0.5
# Neighbours must separate at least this much (in mean log distance) beyond where they
# are one period on, when the noise that made them neighbours no longer counts.  Noise
# alone, a torus, a period-k orbit whose noise is understated three times and a
# settling transient part at most 1.3-fold past it; chaos grows to its bands' size.
MIN_DIVERGENCE_RISE = math.log(2.0)
THEILER_PERIODS = 2  # a neighbour is at least this many periods away in time
MIN_REFERENCES = 20  # neighbour pairs at least, for a mean change of log distance


@dataclass(frozen=True)
class Bands:
    """The periodic skeleton of a motion without a period.

    ``period``: the smallest lag k whose multiples all recur far better than typical
    (1 when none does): the motion visits that many bands in turn.  ``skeleton_period``: the
    multiple of it whose points recur best (bands may hold sub-bands), the orbit whose
    point means are removed before the 0-1 test.
    """

    period: int
    skeleton_period: int


@dataclass(frozen=True)
class Divergence:
    """How nearest neighbours among the strobe points separate, period by period.

    ``curve[j]``: mean change of the neighbour pairs' log distance from one period on
    (where the noise that picked them no longer counts) to j periods on, over the pairs
    still in the record; ``rise``: its greatest value; ``exponent_per_period``: the slope of its
    growth when the rise reaches MIN_DIVERGENCE_RISE, else None (biased low: the noise
    floor flattens the start of the growth); ``references``: the pairs followed;
    ``note`` says what was seen.
    """

    curve: np.ndarray
    rise: float
    exponent_per_period: float | None
    references: int
    note: str

    @property
    def diverges(self) -> bool:
        """True when neighbours separate exponentially from the noise floor."""
        return self.exponent_per_period is not None


def bands_from_recurrence(recurrence: np.ndarray) -> Bands:
    """The bands a motion visits, from its recurrence (median RMS difference of points
    k = 1, 2, ... periods apart, in noise units, as :func:`.judge_regime` gives it).

    Bands of period m show as a dip at every multiple of m tested, at least two of
    them: one lag that happens to recur well is no skeleton.
    """
    recurrence = np.asarray(recurrence, dtype=float)
    finite = np.isfinite(recurrence)
    if not finite.any():
        return Bands(1, 1)
    dip = finite & (recurrence <= BAND_DIP_FRACTION * np.median(recurrence[finite]))
    for period in range(1, finite.size // 2 + 1):
        multiples = np.arange(period, finite.size + 1, period)
        tested = multiples[finite[multiples - 1]]
        if tested.size >= 2 and np.all(dip[tested - 1]):
            return Bands(period, int(tested[np.argmin(recurrence[tested - 1])]))
    return Bands(1, 1)


def zero_one_about_bands(section: np.ndarray, skeleton_period: int, *, seed: int = 0) -> float:
    """K of the 0-1 test on the section less the mean of each of its ``skeleton_period``
    orbit points: the chaotic wandering about the skeleton, which the skeleton's own
    periodic signal would otherwise drown."""
    section = np.asarray(section, dtype=float)
    if skeleton_period < 1:
        raise ValueError(f"skeleton_period = {skeleton_period}: must be at least 1")
    orbit_point = np.arange(section.size) % skeleton_period
    counts = np.bincount(orbit_point, minlength=skeleton_period)
    means = np.bincount(orbit_point, weights=section, minlength=skeleton_period) / counts
    return zero_one_test(section - means[orbit_point], seed=seed).K


def neighbour_divergence(
    points: np.ndarray,
    point_noise_rad: np.ndarray,
    *,
    band_period: int = 1,
    horizon_periods: int | None = None,
) -> Divergence:
    """Follow each strobe point's nearest neighbour in its band and see whether they separate.

    ``points`` (periods x phases, consecutive, finite) are the states of the drive
    period map; ``point_noise_rad`` their noise.  Distances are in units of the noise
    (each phase divided by its median noise), so a pair of noisy copies of one state
    sits at about sqrt(2 phases).  Each point's nearest neighbour is looked for at least
    THEILER_PERIODS and a multiple of ``band_period`` periods away (the same band: a
    pair in two bands of a settling orbit would part by the bands' distance).  Each
    pair is followed while both lie in the record, up to ``horizon_periods`` (default
    half the record: a weak exponent needs long), and its log distance is compared
    with its own one period on, so that the pairs a long lag leaves (the late ones)
    do not shift the curve.
    """
    points = np.asarray(points, dtype=float)
    noise = np.asarray(point_noise_rad, dtype=float)
    if points.ndim != 2 or noise.shape != points.shape:
        raise ValueError(
            f"points {points.shape} and point_noise_rad {noise.shape}: need two equal "
            "(periods, phases) arrays"
        )
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(noise)) and np.all(noise > 0)):
        raise ValueError("points must be finite and their noise finite and > 0")
    if band_period < 1:
        raise ValueError(f"band_period = {band_period}: must be at least 1")
    n = points.shape[0]
    horizon = n // 2 if horizon_periods is None else int(horizon_periods)
    if not 1 <= horizon < n:
        raise ValueError(f"horizon_periods = {horizon}: must be between 1 and {n - 1}")
    states = points / np.median(noise, axis=0)
    rows, pairs = _band_neighbours(states, band_period)
    latest = np.maximum(rows, pairs)  # the pair leaves the record after n - 1 - latest periods
    followed = int(np.count_nonzero(latest + 1 < n))
    if followed < MIN_REFERENCES:
        note = f"{followed} points with a neighbour in their band: too few to follow"
        return Divergence(np.full(2, np.nan), 0.0, None, followed, note)
    log_distance = np.full((horizon + 1, rows.size), np.nan)
    for step in range(horizon + 1):
        inside = latest + step < n
        if np.count_nonzero(inside) < MIN_REFERENCES:
            log_distance = log_distance[:step]
            break
        apart = states[rows[inside] + step] - states[pairs[inside] + step]
        distance = np.linalg.norm(apart, axis=1)
        log_distance[step, inside] = np.log(np.maximum(distance, np.finfo(float).tiny))
    change = log_distance - log_distance[1]
    curve = np.array([np.mean(row[np.isfinite(row)]) for row in change])
    rise = float(np.max(curve[1:]))
    if rise < MIN_DIVERGENCE_RISE:
        note = f"neighbours separate {math.exp(rise):.2g}-fold only past the noise floor"
        return Divergence(curve, rise, None, followed, note)
    # the growth up to its peak: pairs may draw together again after it (a chaotic
    # transient that settles), which is no part of the exponent
    growth = curve[1 : 2 + int(np.argmax(curve[1:]))]
    start, stop = scaling_region(growth)
    slope = float(np.polyfit(np.arange(start, stop), growth[start:stop], 1)[0])
    note = f"neighbours separate {math.exp(rise):.3g}-fold past the noise floor"
    return Divergence(curve, rise, slope, followed, note)


def _band_neighbours(states: np.ndarray, band_period: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows that have a neighbour at least THEILER_PERIODS and a multiple of
    ``band_period`` rows away, and the nearest such neighbour of each."""
    n = states.shape[0]
    index = np.arange(n)
    squared = np.sum(states**2, axis=1)
    nearest = np.full(n, -1)
    chunk = 256  # rows per block: memory stays small for long records
    for first in range(0, n, chunk):
        block = index[first : first + chunk]
        distance = squared[block, None] + squared[None, :] - 2.0 * states[block] @ states.T
        lag = np.abs(block[:, None] - index[None, :])
        distance[(lag <= THEILER_PERIODS) | (lag % band_period != 0)] = np.inf
        best = np.argmin(distance, axis=1)
        found = np.isfinite(distance[np.arange(block.size), best])
        nearest[block[found]] = best[found]
    has = nearest >= 0
    return index[has], nearest[has]
