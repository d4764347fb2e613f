"""Where two explanations' predicted records differ most: a search over forced steps.

Each candidate model runs each drive setting from rest: settled for ``settle_s``, then
dwelt on for ``dwell_s``; the dwell is read as the sensor reads it (the model's
measurement causes, no noise) at 64 drive phases per period, and its last periods (at
most ``COMPARED_PERIODS``) are the prediction.  Two predictions are compared period
against period: each period's curve is matched with the nearest period of the other
prediction, and the RMS of the difference over the period, in units of the record's
noise, is their distance (the larger of the two directions' medians; a period-2 orbit
meets itself whichever drive period it starts on, and two chaotic predictions are compared
as clouds of periods).

Parameter uncertainty: each candidate is also run at ``draws`` parameter sets drawn within
its 95 % intervals (:meth:`~analysis.suggest.candidates.Candidate.draws`).  Its spread at a
setting is the 90th percentile of its draws' distances from its own fitted prediction;
the separation is the distance between the two fitted predictions less both spreads, the
part of the difference that no values within the intervals close (by the triangle
inequality).  Settings are ranked by it.  When both predictions are periodic the
difference is the same at every sample of the dwell, so a record of the dwell's ``n``
samples is expected to give a BIC difference of about ``n x separation^2`` between the
two (for models with as many parameters; each parameter more costs ``ln n``).

Each setting is one task of plain data (:class:`SettingTask`), run here or on Dask
workers by the caller's ``run_map`` (``analysis.maps.MapRunner.map``): the same figures
wherever it ran.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from analysis.model import Drive, RigParameters
from analysis.model_values import measured_angle, model_from_values
from analysis.simulate import SimulationSettings, simulate_packed
from analysis.suggest.candidates import Candidate, CompetingPair

PHASES = 64  # samples per drive period (drive phase 2 pi k / 64)
COMPARED_PERIODS = 64  # the dwell's last periods compared
SPREAD_QUANTILE = 0.9
MAX_PERIOD = 8  # longest period told from an aperiodic response
PERIODIC_TOLERANCE = 0.1  # in noise units: a period repeats to well below the noise
DRAW_SEED = 37
RTOL = 1e-9
ATOL = 1e-11

RunMap = Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]]


@dataclass(frozen=True)
class Setting:
    """A forced step: its drive and how long it is held."""

    frequency_hz: float
    amplitude_m: float
    settle_s: float
    dwell_s: float


@dataclass(frozen=True)
class SettingTask:
    """One setting for every candidate at every parameter set: plain data for a worker."""

    setting: Setting
    rig: dict[str, float]
    models: tuple[tuple[tuple[str, ...], float, tuple[dict[str, float], ...]], ...]
    # each model: its causes, its barrier (rig theta_b), its parameter sets (fitted first)
    pairs: tuple[tuple[int, int], ...]  # indices into models
    noise_rad: float


@dataclass(frozen=True)
class PairAtSetting:
    """Two candidates at one setting: their distance, spreads, separation and regimes."""

    distance: float  # fitted prediction against fitted prediction, noise units
    spread_first: float
    spread_second: float
    regime_first: str
    regime_second: str
    stopped: str = ""  # a simulation did not finish (over the top): why

    @property
    def separation(self) -> float:
        """The distance less both spreads (nan where a simulation stopped)."""
        if self.stopped:
            return math.nan
        return self.distance - self.spread_first - self.spread_second

    @property
    def periodic(self) -> bool:
        """True when both fitted predictions are periodic."""
        return self.regime_first.startswith("period") and self.regime_second.startswith("period")


@dataclass(frozen=True)
class Suggestion:
    """A setting's standing for one pair: what it shows and the expected BIC difference."""

    setting: Setting
    result: PairAtSetting
    samples: int  # the dwell's samples at the record's rate

    @property
    def expected_bic_difference(self) -> float | None:
        """``samples x separation^2`` when both predictions are periodic and the separation
        is positive, else None."""
        s = self.result.separation
        if not self.result.periodic or not s > 0:
            return None
        return self.samples * s * s


@dataclass(frozen=True)
class PairSearch:
    """Every setting searched for one pair, best first."""

    pair: CompetingPair
    ranked: tuple[Suggestion, ...]  # by separation, largest first; stopped ones last

    def best(self, count: int) -> list[Suggestion]:
        """The ``count`` best settings whose separation is positive."""
        return [s for s in self.ranked if s.result.separation > 0][:count]


def settings_grid(frequencies_hz: Sequence[float], amplitudes_m: Sequence[float],
                  settle_s: float, dwell_s: float) -> list[Setting]:
    """Every (frequency, amplitude) pair, frequency-major."""
    return [Setting(float(f), float(a), float(settle_s), float(dwell_s))
            for f in frequencies_hz for a in amplitudes_m]


def search(
    pairs: Sequence[CompetingPair],
    rig: RigParameters,
    settings: Sequence[Setting],
    *,
    noise_rad: float,
    sample_rate_hz: float,
    draws: int = 8,
    run_map: RunMap | None = None,
) -> list[PairSearch]:
    """Every setting for every pair (see the module's docstring); ``run_map`` spreads the
    settings' tasks over workers (None: here, in order)."""
    if not noise_rad > 0:
        raise ValueError(f"noise {noise_rad!r} rad: the differences are counted in units of "
                         "the record's noise, which must be > 0")
    candidates: list[Candidate] = []
    index: dict[str, int] = {}
    for pair in pairs:
        for c in (pair.first, pair.second):
            if c.name not in index:
                index[c.name] = len(candidates)
                candidates.append(c)
    models = tuple(
        (c.causes, c.theta_b_rad,
         (dict(c.values), *c.draws(draws, (DRAW_SEED, number))))
        for number, c in enumerate(candidates))
    pair_index = tuple((index[p.first.name], index[p.second.name]) for p in pairs)
    tasks = [SettingTask(s, rig.as_dict(), models, pair_index, float(noise_rad))
             for s in settings]
    results = run_map(run_setting, tasks) if run_map is not None \
        else [run_setting(task) for task in tasks]
    out = []
    for number, pair in enumerate(pairs):
        rows = [Suggestion(task.setting, result[number],
                           round(task.setting.dwell_s * sample_rate_hz))
                for task, result in zip(tasks, results, strict=True)]
        rows.sort(key=lambda s: (math.isnan(s.result.separation),
                                 -s.result.separation if not math.isnan(s.result.separation)
                                 else 0.0))
        out.append(PairSearch(pair, tuple(rows)))
    return out


def run_setting(task: SettingTask) -> tuple[PairAtSetting, ...]:
    """One setting: every model at every parameter set, and each pair compared (the unit of
    work a worker runs)."""
    rig = RigParameters(**task.rig)
    predictions: list[list[np.ndarray | str]] = [
        [predict(rig, causes, theta_b, values, task.setting) for values in sets]
        for causes, theta_b, sets in task.models]
    sigma = task.noise_rad
    out = []
    for a, b in task.pairs:
        stopped = [p for p in (*predictions[a], *predictions[b]) if isinstance(p, str)]
        if stopped:
            out.append(PairAtSetting(math.nan, math.nan, math.nan, "", "", stopped[0]))
            continue
        first, second = predictions[a], predictions[b]
        out.append(PairAtSetting(
            distance=period_distance(first[0], second[0], sigma),
            spread_first=spread(first, sigma),
            spread_second=spread(second, sigma),
            regime_first=regime(first[0], sigma),
            regime_second=regime(second[0], sigma),
        ))
    return tuple(out)


def predict(rig: RigParameters, causes: Sequence[str], theta_b_rad: float,
            values: Mapping[str, float], setting: Setting) -> np.ndarray | str:
    """The sensor's noiseless reading of the dwell's last periods (periods x ``PHASES``),
    the model started at rest with the drive at phase 0; or, when its simulation stopped,
    why."""
    drive = Drive(amplitude_m=setting.amplitude_m, frequency_hz=setting.frequency_hz)
    model = model_from_values(replace(rig, theta_b_rad=theta_b_rad), drive, True, values,
                              causes)
    periods = math.floor(setting.dwell_s * setting.frequency_hz)
    if periods < 1:
        return (f"a dwell of {setting.dwell_s:g} s holds no whole period at "
                f"{setting.frequency_hz:g} Hz")
    fs = PHASES * setting.frequency_hz
    result = simulate_packed(model.pack(), 0.0, 0.0, settings=SimulationSettings(
        duration_s=periods / setting.frequency_hz, fs_hz=fs, skip_s=setting.settle_s,
        poincare_phase=None, rtol=RTOL, atol=ATOL))
    if result.status != "ok" or result.theta.size < periods * PHASES:
        return (f"{' + '.join(causes) or 'the baseline'} at {setting.frequency_hz:g} Hz, "
                f"{setting.amplitude_m * 1e3:g} mm: {result.status}")
    t = np.arange(periods * PHASES) / fs
    angle = measured_angle(causes, values, t, result.theta[:t.size],
                           theta_dot0=float(result.theta_dot[0]))
    curves = np.asarray(angle, dtype=float).reshape(periods, PHASES)
    return curves[-COMPARED_PERIODS:]


def period_distance(a: np.ndarray, b: np.ndarray, noise_rad: float) -> float:
    """The distance of two predictions (periods x phases) in noise units: each period's RMS
    difference from the nearest period of the other, the median over periods, the larger
    of the two directions."""
    difference = a[:, None, :] - b[None, :, :]
    rms = np.sqrt(np.mean(difference**2, axis=2)) / noise_rad
    return float(max(np.median(rms.min(axis=1)), np.median(rms.min(axis=0))))


def spread(predictions: Sequence[np.ndarray], noise_rad: float) -> float:
    """How far a candidate's draws lie from its fitted prediction (the first): the
    ``SPREAD_QUANTILE`` of their distances; 0 without draws."""
    if len(predictions) < 2:
        return 0.0
    distances = [period_distance(predictions[0], p, noise_rad) for p in predictions[1:]]
    return float(np.quantile(distances, SPREAD_QUANTILE))


def regime(curves: np.ndarray, noise_rad: float) -> str:
    """'period-k' when the prediction's second half repeats every k drive periods (k <=
    ``MAX_PERIOD``, to ``PERIODIC_TOLERANCE`` of the noise), else 'aperiodic' (chaotic or
    quasi-periodic, not told apart here)."""
    curves = curves[curves.shape[0] // 2:]  # the settled half: a transient may linger
    count = curves.shape[0]
    for k in range(1, min(MAX_PERIOD, count - 1) + 1):
        gap = np.max(np.abs(curves[k:] - curves[:-k])) / noise_rad
        if gap < PERIODIC_TOLERANCE:
            return f"period-{k}"
    return "aperiodic"
