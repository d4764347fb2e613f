"""One rig for a whole sweep: its parameters fitted once, shared by every step.

The steps of a sweep are records of one pendulum on one barrier under one sensor, each
with its own drive.  They are fitted together as one multiple-shooting problem
(:class:`~analysis.identify.shooting.ShootingProblem` with one *part* per step): the
rig's parameters (omega, hence L; zeta; K; mu0; the barrier; the sensor's zero) and a
cause's parameters are shared columns; each step has its own drive, measured from its own
tach and table channel as a single forced record's is (:mod:`analysis.identify.drive`),
its own segment states, and its own drive phase where it is fitted (:data:`PER_STEP`,
named ``drive_phase_rad@N`` for step N).  The intervals are the single record's (the
same robust scale, the covariance of the joint problem and the residual's correlation
time), so they are honest across steps: a parameter the steps disagree on cannot have a
narrow interval with white residuals.

The fit goes as a single record's does (:mod:`analysis.identify.forced`), with one more
stage first:

1. each step identified alone over its short segments (equation error, then short
   multiple shooting): its own values of every parameter, side by side;
2. the steps' short segments fitted together, from the steps' median values and their
   own phases and states (a step whose omega alone strays from the median, STRAY_OMEGA,
   from its record's smoothed states and measured drive);
3. the whole of every step in linked segments, half-length first, then full length.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.forced_models import SideBySide, candidate_parameters, record_scale
from analysis.extensions import ModelSpec
from analysis.identify.forced import (
    ForcedData,
    ForcedIdentification,
    ForcedModel,
    forced_data,
    identify_forced,
    inherited_states,
    record_regime,
    record_segments,
    smoothed_states,
    state_steps,
)
from analysis.identify.result import Estimate, IdentificationError
from analysis.identify.shooting import (
    MAX_ITERATIONS,
    FreeParameter,
    Segments,
    ShootingFit,
    ShootingProblem,
)
from analysis.model_values import has_measurement, measured_angle, measurement_has_memory
from analysis.progress import ProgressText
from analysis.sweep.steps import Sweep

# The parameters a step has of its own when they are fitted: its drive's phase (and its
# frequency when neither tach nor table channel timed the drive).
PER_STEP = (q.drive_phase_rad, q.drive_frequency_hz)
# A step identified alone whose omega lies further than this share from the steps' median
# found another basin, not another pendulum (every step swings the one pendulum, whose
# omega a sound step's fit pins to a fraction of a per cent): a period-1 step of a
# frequency sweep that hardly strikes the barrier put omega at 2x and the barrier at 0.3
# rad, and its phase and states, taken as the joint fit's start, left it at 34 x the noise.
# Such a step starts the joint fit from its record instead (its smoothed states, its
# measured drive).
STRAY_OMEGA = 0.1
STEP_MARK = "@"  # drive_phase_rad@3: step 3's own drive phase


def step_name(name: str, number: int) -> str:
    """The name of step ``number``'s own value of ``name``."""
    return f"{name}{STEP_MARK}{number}"


@dataclass(frozen=True)
class SweepData:
    """The fit's view of a sweep: every step's forced record (bad samples out, noise and
    drive measured, segment length for its regime), laid end to end."""

    sweep: Sweep
    steps: tuple[ForcedData, ...]
    regimes: tuple[str, ...]  # each step's regime judged from its record (a label)

    @property
    def numbers(self) -> list[int]:
        """The steps' numbers as recorded."""
        return [s.number for s in self.sweep.steps]

    @property
    def offsets(self) -> np.ndarray:
        """Where each step's samples begin in the joined arrays (and, last, their end)."""
        return np.concatenate([[0], np.cumsum([d.t.size for d in self.steps])])

    @property
    def t(self) -> np.ndarray:
        """Every step's times (each from 0), end to end."""
        return np.concatenate([d.t for d in self.steps])

    @property
    def y(self) -> np.ndarray:
        """Every step's angle (NaN where excluded), end to end."""
        return np.concatenate([d.y for d in self.steps])

    @property
    def valid(self) -> np.ndarray:
        """Every step's good samples, end to end."""
        return np.concatenate([d.valid for d in self.steps])

    @property
    def noise_rad(self) -> float:
        """The sensor's noise: the median of the steps' (one sensor; a step's estimate
        moves with its motion's curvature)."""
        return float(np.median([d.noise_rad for d in self.steps]))

    @property
    def heavy_tailed(self) -> bool:
        """Whether any step's noise has heavy tails (the joint fit is then robust)."""
        return any(d.heavy_tailed for d in self.steps)

    def step_slice(self, k: int) -> slice:
        """Step k's samples (k counts the analysed steps from 0) in the joined arrays."""
        offsets = self.offsets
        return slice(int(offsets[k]), int(offsets[k + 1]))


class StepsNotIdentifiedError(IdentificationError):
    """Steps that cannot be fitted as forced records, each with the reason: the sweep is
    analysed without them (:meth:`~analysis.sweep.steps.Sweep.setting_aside`)."""

    def __init__(self, reasons: Mapping[int, str]) -> None:
        self.reasons = dict(reasons)
        super().__init__("; ".join(f"sweep step {n}: {why}" for n, why in reasons.items()))


def sweep_data(sweep: Sweep) -> SweepData:
    """Each step's record prepared as a forced record is, its regime judged from its own
    strobe points; StepsNotIdentifiedError names the steps that are no forced record fit for a
    fit."""
    steps, regimes, failed = [], [], {}
    for step in sweep.steps:
        try:
            data = forced_data(step.record)
        except IdentificationError as error:
            failed[step.number] = f"not a forced record fit for a fit: {error}"
            continue
        regime = record_regime(step.record, data)
        steps.append(data.for_regime(regime.kind))
        regimes.append(regime.label)
    if failed:
        raise StepsNotIdentifiedError(failed)
    return SweepData(sweep, tuple(steps), tuple(regimes))


def _alone(data: ForcedData, *, threads: int | None = None) -> ForcedIdentification | str:
    """A step identified alone over its short segments, or why it could not be (a value out
    of its physical range, a fit that found no rig)."""
    try:
        return identify_forced(data, whole=False, threads=threads)
    except (IdentificationError, ValueError) as error:
        return f"not identified alone: {error}"


@dataclass(frozen=True)
class SweepModel:
    """How shared values become each step's model: the causes switched on, and each step's
    own values (``name@N``) read as its ``name``."""

    data: SweepData
    causes: tuple[str, ...] = ()

    def step_values(self, values: Mapping[str, float], k: int) -> dict[str, float]:
        """The values step k's model sees: the shared ones and its own."""
        own = STEP_MARK + str(self.data.numbers[k])
        out = {n: v for n, v in values.items() if STEP_MARK not in n}
        out |= {n[:-len(own)]: v for n, v in values.items() if n.endswith(own)}
        return out

    def packs(self) -> list[Callable[[Mapping[str, float]], np.ndarray]]:
        """Each step's packed model as a function of the shared values."""
        def pack(k: int) -> Callable[[Mapping[str, float]], np.ndarray]:
            model = ForcedModel(self.data.steps[k], self.causes)
            return lambda values: model.packed(self.step_values(values, k))
        return [pack(k) for k in range(len(self.data.steps))]

    def measure(self, values: Mapping[str, float], t: np.ndarray, theta: np.ndarray,
                theta_dot0: float | None = None) -> np.ndarray:
        """The angle the sensor (one for every step) reports over a stretch of samples."""
        return measured_angle(self.causes, values, t, theta, theta_dot0)

    def problem(self, segments: JoinedSegments, free: Sequence[FreeParameter],
                fixed: Mapping[str, float], *, threads: int | None = None) -> ShootingProblem:
        """The joint multiple-shooting problem of this model on every step."""
        d = self.data
        return ShootingProblem(
            d.t, d.y, d.valid, d.noise_rad, segments.segments, self.packs(), list(free),
            fixed, part_of_segment=segments.part,
            measure=self.measure if has_measurement(self.causes) else None,
            measure_has_memory=measurement_has_memory(self.causes),
            rate_scale=float(np.mean([s.drive.omega_rad_s for s in d.steps])),
            threads=threads, robust=d.heavy_tailed,
        )


@dataclass(frozen=True)
class JoinedSegments:
    """Every step's segments in the joined arrays, and the step (part) of each."""

    segments: Segments
    part: np.ndarray
    each: tuple[Segments, ...]  # each step's own, in its own sample numbers


def joined(data: SweepData, each: Sequence[Segments]) -> JoinedSegments:
    """Each step's segments moved to its place in the joined arrays; a step's last segment
    is never linked to the next step's first."""
    offsets = data.offsets
    parts = [(s, int(offsets[k])) for k, s in enumerate(each)]
    linked = [s.linked.copy() for s, _ in parts]
    for link in linked:
        link[-1] = False
    return JoinedSegments(
        Segments(np.concatenate([s.start + o for s, o in parts]),
                 np.concatenate([s.fit_stop + o for s, o in parts]),
                 np.concatenate([s.stop + o for s, o in parts]),
                 np.concatenate([s.end_s for s, _ in parts]),
                 np.concatenate(linked)),
        np.concatenate([np.full(s.count, k) for k, (s, _) in enumerate(parts)]),
        tuple(each))


def sweep_state_steps(data: SweepData) -> tuple[float, float]:
    """Finite-difference steps of a segment's state: the largest step's (by its swing)."""
    return max((state_steps(d) for d in data.steps), key=lambda h: h[0])


def sweep_parameters(
    data: SweepData, model: ModelSpec, start: Mapping[str, float],
    hints: Mapping[str, float], *, phase_free: bool,
) -> list[FreeParameter]:
    """Free parameters of ``model`` on the sweep: the shared ones as a single record's
    (:func:`~analysis.discrepancy.forced_models.candidate_parameters`, sized on the step
    with the largest swing), and each step's own (:data:`PER_STEP`: the drive phase when
    ``phase_free`` or the drive is untimed, the frequency when untimed), started at
    ``start``'s ``name@N``."""
    largest = max(range(len(data.steps)),
                  key=lambda k: float(np.nanmax(data.steps[k].y) - np.nanmin(data.steps[k].y)))
    reference = data.steps[largest]
    local = {**start, **{n: start[step_name(n, data.numbers[largest])] for n in PER_STEP
                         if step_name(n, data.numbers[largest]) in start}}
    shared = [p for p in candidate_parameters(reference, model, local,
                                              record_scale(reference, local), hints)
              if p.name not in PER_STEP]
    own = []
    for k, (number, d) in enumerate(zip(data.numbers, data.steps, strict=True)):
        if phase_free or not d.drive.timing_known:
            phase = start.get(step_name(q.drive_phase_rad, number), d.drive.phase0_rad)
            own.append(FreeParameter(step_name(q.drive_phase_rad, number), phase, 1e-5, False,
                                     phase - math.pi, phase + math.pi, part=k))
        if not d.drive.timing_known:
            f = start.get(step_name(q.drive_frequency_hz, number), d.drive.frequency_hz)
            own.append(FreeParameter(step_name(q.drive_frequency_hz, number), f, 1e-8, True,
                                     0.99 * f, 1.01 * f, part=k))
    return shared + own


@dataclass
class SweepIdentification:
    """The rig identified once for the whole sweep."""

    data: SweepData
    model: SweepModel
    fit: ShootingFit  # over every step in linked segments
    segments: JoinedSegments
    alone: tuple[ForcedIdentification, ...]  # each step identified alone (short segments)
    start: dict[str, float]  # where the joint fit started (the steps' medians, own phases)

    def step_rms(self, k: int) -> float:
        """RMS residual of the joint fit over step k's fitted samples [rad]."""
        r = self.fit.residual[self.data.step_slice(k)]
        r = r[np.isfinite(r)]
        return float(math.sqrt(np.mean(r * r))) if r.size else math.nan

    def step_estimates(self, k: int) -> dict[str, Estimate]:
        """Step k's own fitted values (its drive phase, ...) with their intervals."""
        own = STEP_MARK + str(self.data.numbers[k])
        return {n[:-len(own)]: e for n, e in self.fit.estimates.items() if n.endswith(own)}


def identify_sweep(
    data: SweepData, *, progress: ProgressText | None = None, threads: int | None = None,
) -> SweepIdentification:
    """Identify the rig once for every step (see the module's docstring); the steps that
    cannot be identified alone are named, with the reason, by StepsNotIdentifiedError."""
    say = progress or (lambda message: None)
    n = len(data.steps)
    alone: list[ForcedIdentification] = []
    with SideBySide(threads) as batch:
        pending = [batch.add(_alone, d) for d in data.steps]
    failed = {number: found.result for number, found in zip(data.numbers, pending, strict=True)
              if isinstance(found.result, str)}
    if failed:
        raise StepsNotIdentifiedError(failed)
    for k, found in enumerate(pending):
        alone.append(found.result)
        values = found.result.short_fit.values
        say(f"step {k + 1} of {n} (step {data.numbers[k]}) identified alone: "
            + ", ".join(f"{name} {values[name]:.4g}" for name in
                        (q.omega_rad_s, q.zeta, q.K_N_per_m1_5, q.theta_b_rad)))
    causes = alone[0].model.causes  # the identification's: barrier, sensor zero, [amplitude]
    model = SweepModel(data, causes)
    start: dict[str, float] = {}
    shared_names = [name for name in alone[0].short_fit.values if name not in PER_STEP]
    for name in shared_names:
        start[name] = float(np.median([a.short_fit.values[name] for a in alone]))
    stray = _strays(data, alone, start[q.omega_rad_s], say)
    for k, (number, a) in enumerate(zip(data.numbers, alone, strict=True)):
        measured = {q.drive_phase_rad: data.steps[k].drive.phase0_rad,
                    q.drive_frequency_hz: data.steps[k].drive.frequency_hz}
        for name in PER_STEP:
            if name in a.short_fit.values:
                start[step_name(name, number)] = (measured[name] if k in stray
                                                  else a.short_fit.values[name])
    free = sweep_parameters(data, ModelSpec(causes), start, start, phase_free=True)
    hs = sweep_state_steps(data)
    short = joined(data, [a.short for a in alone])
    say(f"the steps' short segments fitted together ({short.segments.count} segments, "
        f"{len(free)} parameters)")
    problem = model.problem(short, free, {}, threads=threads)
    offset = start.get(q.offset_rad, 0.0)
    states = [smoothed_states(d, a.short.start, offset) if k in stray else a.short_fit.states
              for k, (d, a) in enumerate(zip(data.steps, alone, strict=True))]
    fit_short = problem.fit(np.concatenate(states), state_steps=hs)
    say(f"  rms {fit_short.rms / data.noise_rad:.3g} x noise after {fit_short.iterations} "
        "iterations")
    fit, segments = fit_sweep_over_record(model, _restarted(free, fit_short.values), {},
                                          threads=threads, progress=say)
    return SweepIdentification(data, model, fit, segments, tuple(alone), start)


def _strays(data: SweepData, alone: Sequence[ForcedIdentification], omega: float,
            say: ProgressText) -> set[int]:
    """The steps (counted from 0) whose fit alone put omega further than STRAY_OMEGA from
    the steps' median ``omega``."""
    out = set()
    for k, a in enumerate(alone):
        own = a.short_fit.values[q.omega_rad_s]
        if abs(own / omega - 1.0) > STRAY_OMEGA:
            out.add(k)
            say(f"  step {data.numbers[k]} alone put omega at {own:.4g} rad/s against the "
                f"steps' {omega:.4g}: it starts the joint fit from its record")
    return out


def fit_sweep_over_record(
    model: SweepModel, free: Sequence[FreeParameter], fixed: Mapping[str, float], *,
    threads: int | None = None, progress: ProgressText | None = None,
    start_from: tuple[ShootingFit, JoinedSegments] | None = None,
    max_iterations: int = MAX_ITERATIONS,
) -> tuple[ShootingFit, JoinedSegments]:
    """Multiple shooting over every step in linked segments of its ``segment_s``, reached
    as a single record's (:func:`~analysis.identify.forced.fit_over_record`): half-length
    segments first from a smoother's states, then full length from theirs; or from
    ``start_from``'s states when given."""
    say = progress or (lambda message: None)
    data = model.data
    values = {**fixed, **{p.name: p.start for p in free}}
    offset = values.get(q.offset_rad, 0.0)
    hs = sweep_state_steps(data)
    full = joined(data, [record_segments(d) for d in data.steps])
    smooth = joined_smoothed_states(data, full, offset)
    if start_from is not None:
        states = joined_inherited_states(full, start_from[1], start_from[0].states, smooth)
        problem = model.problem(full, free, fixed, threads=threads)
        return problem.fit(states, state_steps=hs, max_iterations=max_iterations), full
    half = joined(data, [record_segments(d, 0.5 * d.segment_s) for d in data.steps])
    say(f"multiple shooting over every step in {half.segments.count} linked segments")
    problem = model.problem(half, free, fixed, threads=threads)
    states = problem.fit_states(joined_smoothed_states(data, half, offset), state_steps=hs)
    fit_half = problem.fit(states, state_steps=hs, max_iterations=max_iterations)
    say(f"  rms {fit_half.rms / data.noise_rad:.3g} x noise after {fit_half.iterations} "
        "iterations")
    states = joined_inherited_states(full, half, fit_half.states, smooth)
    say(f"multiple shooting over every step in {full.segments.count} linked segments")
    problem = model.problem(full, _restarted(free, fit_half.values), fixed, threads=threads)
    fit = problem.fit(states, state_steps=hs, max_iterations=max_iterations)
    say(f"  rms {fit.rms / data.noise_rad:.3g} x noise after {fit.iterations} iterations")
    return fit, full


def _restarted(free: Sequence[FreeParameter], values: Mapping[str, float]
               ) -> list[FreeParameter]:
    """The free parameters started at ``values``."""
    return [replace(p, start=values[p.name]) for p in free]


def joined_smoothed_states(data: SweepData, segments: JoinedSegments, offset: float) -> np.ndarray:
    """Each step's segment states from its smoothed record (a start for the fit)."""
    return np.concatenate([smoothed_states(d, s.start, offset)
                           for d, s in zip(data.steps, segments.each, strict=True)])


def joined_inherited_states(new: JoinedSegments, old: JoinedSegments, old_states: np.ndarray,
               fallback: np.ndarray) -> np.ndarray:
    """Step by step, the states of ``old``'s segments that start where ``new``'s do."""
    out, at_new, at_old = [], 0, 0
    for seg_new, seg_old in zip(new.each, old.each, strict=True):
        out.append(inherited_states(seg_new, seg_old, old_states[at_old:at_old + seg_old.count],
                                    fallback[at_new:at_new + seg_new.count]))
        at_new += seg_new.count
        at_old += seg_old.count
    return np.concatenate(out)


def shared_json(fit: ShootingFit) -> dict[str, dict[str, Any]]:
    """The shared fitted values with their 95 % intervals (each step's own left out)."""
    return {name: e.as_json() for name, e in fit.estimates.items() if STEP_MARK not in name}
