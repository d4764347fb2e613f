"""The true regime of a noiseless reference run: period k from the stroboscopic states, else
the largest Lyapunov exponent from a twin trajectory decides chaos.

This is the truth a forced record's regime judgement is scored against, so it works on
the exact states (theta, theta') at drive phase 0, never on measured data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reference.simulator import Pendulum, TableMotion, simulate_reference

MAX_PERIOD = 32
# Points k drive periods apart agree to this fraction of the attractor's extent on a
# settled period-k orbit: far above the integration error (rtol 1e-10), far below noise.
PERIOD_TOLERANCE = 1e-6
# Initial twin separation, as a fraction of the attractor's extent.
TWIN_SEPARATION = 1e-7
# The smallest relative gap between twin and base that rounding lets us resolve.
RESOLVABLE_GAP = 1e-16
# Exponents within this many nats per drive period of zero count as neither chaotic nor
# contracting: quasi-periodic.
LYAPUNOV_MARGIN_PER_PERIOD = 0.01


@dataclass(frozen=True)
class RegimeTruth:
    """What the motion over the record is.

    ``regime``: "periodic" (period 1), "period-k" (k = 2..32), "chaotic" (no period, twin
    exponent clearly positive), "quasi-periodic" (no period, exponent near zero) or
    "unsettled" (no period yet, exponent clearly negative: a transient still dying).
    The period is judged on the record's second half; ``settling`` is the largest
    relative distance between stroboscopic points ``period`` apart over the whole
    record, which tells how settled its start still is.  ``lyapunov_per_s`` is computed
    only when no period is found.
    """

    regime: str
    period: int | None
    lyapunov_per_s: float | None
    settling: float | None

    @property
    def is_periodic(self) -> bool:
        """True for period-1 and period-k motion."""
        return self.period is not None


def strobe_times(table: TableMotion, t_start_s: float, t_end_s: float) -> np.ndarray:
    """The instants in [t_start, t_end] at which the drive phase is a multiple of 2 pi."""
    frequency = table.frequency_hz
    first = math.ceil(table.phase(t_start_s) / (2.0 * math.pi) - 1e-12)
    last = math.floor(table.phase(t_end_s) / (2.0 * math.pi) + 1e-12)
    k = np.arange(first, last + 1, dtype=float)
    times = (2.0 * math.pi * k - table.phase_rad) / (2.0 * math.pi * frequency)
    return times[(times >= t_start_s) & (times <= t_end_s)]


def attractor_extent(theta_rad: np.ndarray, theta_dot_rad_s: np.ndarray) -> np.ndarray:
    """Peak-to-peak extent of the motion in theta and theta' (the scale of 'agree')."""
    return np.array([np.ptp(theta_rad), np.ptp(theta_dot_rad_s)])


def stroboscopic_mismatch(points: np.ndarray, extent: np.ndarray, k: int) -> np.ndarray:
    """Relative distance between stroboscopic points k periods apart, one per pair."""
    difference = (points[k:] - points[:-k]) / extent
    return np.max(np.abs(difference), axis=1)


def find_period(points: np.ndarray, extent: np.ndarray) -> int | None:
    """The smallest k <= 32 whose points k periods apart agree within tolerance over the
    second half of the record, or None.  At least two comparisons are needed per k."""
    settled = points[points.shape[0] // 2 :]
    for k in range(1, MAX_PERIOD + 1):
        if settled.shape[0] < k + 2:
            return None
        if np.max(stroboscopic_mismatch(settled, extent, k)) <= PERIOD_TOLERANCE:
            return k
    return None


def twin_lyapunov_per_s(
    pendulum: Pendulum,
    table: TableMotion,
    strobe_s: np.ndarray,
    points: np.ndarray,
    extent: np.ndarray,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
) -> float:
    """Largest Lyapunov exponent [1/s]: a twin started a small distance from each
    stroboscopic state is carried one drive period and renormalised (Benettin)."""
    direction = np.array([1.0, 1.0]) / math.sqrt(2.0)
    separation = TWIN_SEPARATION
    logs: list[float] = []
    for j in range(strobe_s.size - 1):
        start = points[j] + separation * direction * extent
        twin = simulate_reference(
            pendulum, table, float(start[0]), float(start[1]), np.array([strobe_s[j + 1]]),
            t_start_s=float(strobe_s[j]), rtol=rtol, atol=atol,
        )
        gap = (twin.final_state[:2] - points[j + 1]) / extent
        distance = float(np.hypot(gap[0], gap[1]))
        # a twin that merged with the base (both stuck) counts as contracted to rounding
        logs.append(math.log(max(distance, RESOLVABLE_GAP) / separation))
        if distance > RESOLVABLE_GAP:
            direction = gap / distance
    return float(np.mean(logs)) / float(np.mean(np.diff(strobe_s)))


def judge_regime(
    pendulum: Pendulum,
    table: TableMotion,
    strobe_s: np.ndarray,
    points: np.ndarray,
    extent: np.ndarray,
) -> RegimeTruth:
    """Period k when the stroboscopic points repeat; otherwise the twin exponent's sign
    decides chaotic, quasi-periodic or unsettled."""
    period = find_period(points, extent)
    if period is not None:
        settling = float(np.max(stroboscopic_mismatch(points, extent, period)))
        regime = "periodic" if period == 1 else f"period-{period}"
        return RegimeTruth(regime, period, None, settling)
    exponent = twin_lyapunov_per_s(pendulum, table, strobe_s, points, extent)
    per_period = exponent / table.frequency_hz
    if per_period > LYAPUNOV_MARGIN_PER_PERIOD:
        regime = "chaotic"
    elif per_period < -LYAPUNOV_MARGIN_PER_PERIOD:
        regime = "unsettled"
    else:
        regime = "quasi-periodic"
    return RegimeTruth(regime, None, exponent, None)


# A record cannot tell period k from its divisor p when its stroboscopic angles p periods
# apart differ by less than this fraction of the angle noise all over its settled end: one
# sample per drive period carries that noise, and the difference hides in it.
UNRESOLVED_OVER_NOISE = 0.1


def periods_a_record_shows(
    points: np.ndarray, noise_rad: float, truth: RegimeTruth
) -> set[int]:
    """The periods a judgement of the noisy record may rightly give: the true one, and each
    divisor p of it whose splitting (angles p periods apart over the second half of the
    record) stays below ``UNRESOLVED_OVER_NOISE`` of the noise.  For chaos or quasi-periodic
    motion, a period p whose points agree that closely over the last quarter (the motion
    ends periodic, or so nearly that the record cannot tell).  Empty when none."""
    if noise_rad <= 0.0:
        raise ValueError(f"noise_rad = {noise_rad!r}: expected the angle noise, > 0")
    angles = points[:, 0]
    settled = angles[angles.size // 2 :] if truth.period else angles[3 * angles.size // 4 :]
    shown = {truth.period} if truth.period else set()
    for p in range(1, (truth.period or MAX_PERIOD + 1)):
        if truth.period and truth.period % p:
            continue
        if settled.size < p + 2:
            break
        if np.max(np.abs(settled[p:] - settled[:-p])) < UNRESOLVED_OVER_NOISE * noise_rad:
            shown.add(p)
            if not truth.period:
                break
    return shown
