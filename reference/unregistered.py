"""Forced records with an effect that no named cause of docs/MODEL.md section 6 describes:
in the physics, the sensor, the drive, or the noise (a decoy: the baseline with heavy-tailed
noise).  The analysis must not explain them with a named cause; it should say that
something is left unexplained, and, where the effect leaves one, give the finding of the
right kind (a line, a trend, the drive frequency, the timing).

Each effect is drawn (seeded) at a size a real rig can have and that shows: what the
baseline cannot absorb by refitting its own parameters reaches the visibility threshold
of :mod:`reference.visibility` (the drive's frequency and the tach's timing show in
the drive channels instead).  Records come from the reference simulator, as the named
causes' do (:mod:`reference.forced_records`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from reference.forced_records import (
    CauseHiddenError,
    ForcedCase,
    draw_forced_case,
    simulate_true_motion,
    visibility_of,
    with_motion,
)
from reference.frozen import frozen
from reference.regime_truth import attractor_extent, judge_regime
from reference.simulator import OverTheTopError

SIZES = (1.0, 2.0)  # a drawn size, then twice it, before the record is drawn again
ATTEMPTS = 8  # records drawn (seed, seed + 100 000, ...) before giving up


@dataclass(frozen=True)
class Effect:
    """An effect outside the registry: where it acts, the finding kind it should leave
    (None: only that something is unexplained), and how its size is drawn (from the
    random generator, the clean case and a size multiplier)."""

    domain: str  # physics, sensor, drive or noise
    finding: str | None
    draw: Callable[[np.random.Generator, ForcedCase, float], dict[str, float]]
    moves_the_pendulum: bool = False  # the motion is simulated again with the effect
    shown_by_visibility: bool = True  # sized until the baseline cannot absorb it
    needs_laser: bool = False


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


def _amplitude(case: ForcedCase) -> float:
    return float(np.max(np.abs(case.motion.theta_rad)))


def _hairspring(rng, case, size):
    """A cubic restoring torque at the pivot (a stiffening cable to the sensor): at the
    swing's peak it adds 4-12 % to gravity's restoring acceleration."""
    share = size * rng.uniform(0.04, 0.12)
    return {"c3_per_s2": _sign(rng) * share * case.rig.omega_rad_s**2 / _amplitude(case)**2}


def _warming(rng, case, size):
    """The barrier softens as it warms: its stiffness falls 20-45 % over the record."""
    fall = min(size * rng.uniform(0.20, 0.45), 0.8)
    return {"K_drift_per_s": -fall / case.duration_s}


def _hum(rng, case, size):
    """Interference at a frequency no drive harmonic or subharmonic is near (a fan, a
    ground loop), 1-3 noise sigmas in amplitude."""
    half = case.drive.stated_frequency_hz / 2.0
    while True:
        frequency = float(rng.uniform(13.0, 47.0))
        if abs(math.remainder(frequency, half)) > 0.25 * half:
            break
    return {"amplitude_rad": size * rng.uniform(1.0, 3.0) * case.measurement.angle_noise_rad,
            "frequency_hz": frequency, "phase_rad": float(rng.uniform(0.0, 2.0 * math.pi))}


def _gain_drift(rng, case, size):
    """The sensor's gain drifts 3-8 % over the record (a supply voltage sagging)."""
    return {"gain_change": _sign(rng) * size * rng.uniform(0.03, 0.08)}


def _zero_drift(rng, case, size):
    """The sensor's zero drifts 4-10 noise sigmas over the record (warming up)."""
    return {"offset_change_rad":
            _sign(rng) * size * rng.uniform(4.0, 10.0) * case.measurement.angle_noise_rad}


def _frequency_off(rng, case, size):
    """The generator runs 0.3-1.5 % off the frequency in the lab's notes."""
    return {"relative": _sign(rng) * size * rng.uniform(0.003, 0.015)}


def _tach_delay(rng, case, size):
    """The tach's pulse lags the table's phase zero by 3-10 % of a period."""
    return {"delay_s": size * rng.uniform(0.03, 0.10) / case.drive.stated_frequency_hz}


def _gain_wander(rng, case, size):
    """The shaker amplifier's gain wanders by 4-10 % over 15-25 s."""
    return {"depth": min(size * rng.uniform(0.04, 0.10), 0.3),
            "frequency_hz": float(rng.uniform(0.04, 0.067)),
            "phase_rad": float(rng.uniform(0.0, 2.0 * math.pi))}


def _heavy_tails(rng, case, size):
    """Student's t noise with 1.5-3 degrees of freedom (spikes), same median size."""
    return {"dof": float(rng.uniform(1.5, 3.0))}


EFFECTS: dict[str, Effect] = {
    "pivot_hairspring": Effect("physics", None, _hairspring, moves_the_pendulum=True),
    "barrier_warming": Effect("physics", None, _warming, moves_the_pendulum=True),
    "sensor_hum": Effect("sensor", "line", _hum),
    "sensor_gain_drift": Effect("sensor", "trend", _gain_drift),
    "sensor_zero_drift": Effect("sensor", "trend", _zero_drift),
    "drive_frequency_off": Effect("drive", "drive_frequency", _frequency_off,
                                  moves_the_pendulum=True, shown_by_visibility=False),
    "tach_delay": Effect("drive", "timing", _tach_delay, shown_by_visibility=False,
                         needs_laser=True),
    "drive_gain_wander": Effect("drive", None, _gain_wander, moves_the_pendulum=True),
    "heavy_tailed_noise": Effect("noise", "outliers", _heavy_tails, shown_by_visibility=False),
}


@frozen(restore=with_motion)
def draw_unregistered_case(
    seed: int, effect: str, *, frequency_hz: float | None = None, duration_s: float = 60.0,
) -> ForcedCase:
    """A clean forced record from ``seed`` with ``effect`` added at a size that shows.

    Records where no size tried shows, or that the effect drives over the top, are drawn
    again from seed + 100 000 k."""
    if effect not in EFFECTS:
        raise ValueError(f"effect = {effect!r}: expected one of {', '.join(EFFECTS)}")
    spec = EFFECTS[effect]
    reasons = []
    for attempt in range(ATTEMPTS):
        base = draw_forced_case(seed + 100_000 * attempt, "none", frequency_hz=frequency_hz,
                                duration_s=duration_s, laser=True if spec.needs_laser else None)
        rng = np.random.default_rng([seed, attempt, 11])
        for size in SIZES:
            try:
                case = with_effect(base, effect, spec.draw(rng, base, size))
            except OverTheTopError:
                reasons.append("over the top")
                break
            if not spec.shown_by_visibility or case.visibility.shows:
                return case
            reasons.append(f"{case.visibility.visible_over_noise:.2g} x noise")
    raise CauseHiddenError(f"seed {seed}: {effect} never showed ({', '.join(reasons)})")


def with_effect(base: ForcedCase, effect: str, values: dict[str, float], *,
                judged: bool = True) -> ForcedCase:
    """The clean case ``base`` with one effect: its motion simulated again when the effect
    moves the pendulum, and (``judged``) the regime judged again and how much of it shows."""
    spec = EFFECTS[effect]
    case = replace(base, effects={effect: values})
    if effect == "drive_frequency_off":
        case = replace(case, drive=replace(
            case.drive, frequency_hz=case.drive.frequency_hz * (1.0 + values["relative"])))
    motion = base.motion
    if spec.moves_the_pendulum:
        motion = simulate_true_motion(case)
    if spec.moves_the_pendulum and judged:
        extent = attractor_extent(motion.theta_rad, motion.theta_dot_rad_s)
        case = replace(case, regime_truth=judge_regime(
            case.pendulum(), case.table(), motion.strobe_s, motion.strobe_states, extent))
    visibility = visibility_of(case, motion) if spec.shown_by_visibility and judged else None
    return replace(case, motion=motion, visibility=visibility)
