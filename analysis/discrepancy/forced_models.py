"""How each model is fitted to a forced record: the two ways the record is cut, the
parameters a model frees and where they start, a first fit over short segments from a
cold start, and the fits over the whole record."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.candidates import plan_for
from analysis.discrepancy.fitting import FitData, FitResult
from analysis.experiments import FORCED
from analysis.extensions import ModelSpec, RecordScale, cause
from analysis.identify.forced import (
    BASELINE_PLANS,
    ForcedData,
    ForcedIdentification,
    ForcedModel,
    clock_parameter,
    fit_model,
    fit_over_record,
    free_parameters,
    hertz_penetration_rad,
    impact_speed,
    record_segments,
    smoothed_states,
)
from analysis.identify.shooting import FreeParameter, Segments, ShootingFit, thread_count
from analysis.model_values import has_measurement, measured_angle, measurement_has_memory

SCREEN_ITERATIONS = 20  # every candidate, over short segments, from the cold start
# Over the record every model starts from its screening solution: a right one converges in
# a few iterations, a wrong one crawls, and more of its crawl would change no judgement.
REFINE_ITERATIONS = 12


Fit = TypeVar("Fit")


class Pending(Generic[Fit]):
    """A fit added to :class:`SideBySide`; its ``result`` once the batch has run."""

    def __init__(self) -> None:
        self._done = False
        self._result: Any = None

    @property
    def result(self) -> Fit:
        """The fit's result (an error before the batch has run)."""
        if not self._done:
            raise RuntimeError("SideBySide: read a result after the batch has run")
        return self._result

    def _set(self, result: Fit) -> None:
        self._result, self._done = result, True


class SideBySide:
    """Independent fits run at once, a thread each, as many at a time as ``threads`` allows,
    each called where it is added, with the threads it may use as its keyword ``threads``::

        with SideBySide(threads) as batch:
            parent = batch.add(refit, data, model, fit, lay)
            nested = {name: batch.add(extend, data, model, fit, name, segments)
                      for name in names}
        parent.result, nested[name].result

    A fit given two threads leaves one idle through its steps' linear algebra, which one
    thread runs; one fit per core keeps both busy (the screening of 11 models: 11.9 s one
    after another, 9.5 s side by side, on 2 cores).  A fit's numbers do not depend on its
    thread count, so neither do the results.  Alone (or on one core), a fit is given every
    thread."""

    def __init__(self, threads: int | None) -> None:
        self.threads = threads
        self._calls: list[tuple[Callable[..., Any], tuple, dict[str, Any], Pending]] = []

    def add(self, fit: Callable[..., Fit], *args: Any, **kwargs: Any) -> Pending[Fit]:
        """``fit(*args, threads=..., **kwargs)`` to run with the batch."""
        pending: Pending[Fit] = Pending()
        self._calls.append((fit, args, kwargs, pending))
        return pending

    def run(self) -> None:
        """Run every fit added (once)."""
        calls, self._calls = self._calls, []
        cores = thread_count(self.threads)
        if cores <= 1 or len(calls) <= 1:
            for fit, args, kwargs, pending in calls:
                pending._set(fit(*args, threads=self.threads, **kwargs))
            return
        with ThreadPoolExecutor(min(cores, len(calls)), thread_name_prefix="models") as pool:
            futures = [pool.submit(fit, *args, threads=1, **kwargs)
                       for fit, args, kwargs, _ in calls]
            for (*_, pending), future in zip(calls, futures, strict=True):
                pending._set(future.result())

    def __enter__(self) -> SideBySide:
        return self

    def __exit__(self, kind: object, error: object, trace: object) -> None:
        if error is None:
            self.run()


@dataclass(frozen=True)
class ModelFits:
    """One model fitted to the whole record and (when it is judged on forecasts) to the
    alternating training stretches."""

    model: ModelSpec
    full: ShootingFit
    train: ShootingFit | None = None


@dataclass(frozen=True)
class Layouts:
    """The two ways the record is cut: linked segments over everything, and alternating
    fitted and forecast stretches (their starts are every other segment's start)."""

    full: Segments
    train: Segments


def layouts(data: ForcedData) -> Layouts:
    """Segments of the record's length over it; training stretches as long, each followed
    by a forecast one as long again."""
    return Layouts(record_segments(data), record_segments(data, heldout_s=data.segment_s))


def fit_data_view(data: ForcedData) -> FitData:
    """The forced record as the shared report and localisation code sees a record."""
    return FitData(
        experiment=FORCED.name, t=data.t, y=data.y, valid=data.valid, noise_rad=data.noise_rad,
        rig=data.rig, drive=data.drive.model_drive(), barrier=True,
        phase0_rad=data.drive.phase0_rad,
    )


def as_fit_result(fit: ShootingFit, model: ModelSpec, contacts: int = 0) -> FitResult:
    """A shooting fit of ``model`` as the judges and reports of every experiment see a fit."""
    return FitResult(
        model=model, values=dict(fit.values), estimates=dict(fit.estimates),
        residual=fit.residual, n_params=fit.n_params, success=fit.success,
        message=fit.message, contacts=contacts,
    )


def record_scale(data: ForcedData, values: Mapping[str, float]) -> RecordScale:
    """Magnitudes that size the candidates' steps and start values: the penetration of a
    Hertz impact at the speed the record's highest angle implies."""
    omega = values[q.omega_rad_s]
    speed = impact_speed(data, float(np.nanmax(data.y)))
    K = values.get(q.K_N_per_m1_5, data.rig.K_N_per_m1_5)
    return RecordScale.of(data.rig, data.t, data.y, values,
                          data.rig.l_m * hertz_penetration_rad(data.rig, omega, K, speed))


def cause_hints(ident: ForcedIdentification) -> dict[str, float]:
    """What the record says about the causes' parameters before any cause is fitted: the
    identified barrier and sensor zero, the table channel's amplitude and harmonic (or the
    identified amplitude when there is no table channel)."""
    values = ident.values
    hints = {q.theta_b_rad: values[q.theta_b_rad], q.offset_rad: values[q.offset_rad]}
    drive = ident.data.drive
    if drive.phase_known:
        # a sensor lagging by tau reads the response the drive caused Omega tau earlier
        delay = -math.remainder(values[q.drive_phase_rad] - drive.phase0_rad, 2 * math.pi) \
            / drive.omega_rad_s
        if delay > 0:
            hints[q.tau_s] = delay
    if drive.table is not None:
        hints |= {name: size.value for name, size in drive.measured_sizes().items()}
        hints[q.phi2_rad] = drive.table.phi2_rad.value
    elif q.eps in values:
        hints[q.eps] = values[q.eps]
    return hints


def level_hints(model: ModelSpec, hints: Mapping[str, float]) -> dict[str, float]:
    """The hints for model ``model``: where it holds only one of the barrier and the sensor
    zero, that one takes the whole measured stop level (the identified barrier plus zero),
    since a swing's stops are what the record fixes most sharply; the identification's
    split between the two can be far off when a cause it lacks bends it (a barrier 0.158
    and a zero -0.175 rad for a true barrier -0.025 and zero 0 under a sensor cubic)."""
    out = dict(hints)
    present = set(model.causes)
    if q.theta_b_rad in hints and q.offset_rad in hints:
        level = hints[q.theta_b_rad] + hints[q.offset_rad]
        if "barrier_offset" in present and "sensor_offset" not in present:
            out[q.theta_b_rad] = level
        elif "sensor_offset" in present and "barrier_offset" not in present:
            out[q.offset_rad] = level
    return out


def baseline_names(data: ForcedData, model: ModelSpec) -> list[str]:
    """The baseline parameters a fit of model ``model`` adjusts (a cause may take over one's
    role)."""
    replaced = {r for c in model.causes for r in cause(c).replaces}
    return [n for n in BASELINE_PLANS if n not in replaced]


def candidate_parameters(
    data: ForcedData, model: ModelSpec, start: Mapping[str, float], scale: RecordScale,
    hints: Mapping[str, float],
) -> list[FreeParameter]:
    """Free parameters of model ``model``: the baseline extended by its causes."""
    extra = []
    if not data.drive.timing_known:
        extra.append(clock_parameter(start[q.drive_frequency_hz]))
        phase = start[q.drive_phase_rad]
        extra.append(FreeParameter(q.drive_phase_rad, phase, 1e-5, False, phase - math.pi,
                                   phase + math.pi))
    for c in map(cause, model.causes):
        plans = plan_for(c, scale)
        for spec in c.parameters:
            plan = plans[spec.name]
            value = hints.get(spec.name, start.get(spec.name, plan.start))
            value = min(max(value, spec.lower), spec.upper)
            if plan.log:
                value = max(value, spec.lower if spec.lower > 0 else 1e-12)
            extra.append(FreeParameter(spec.name, value, plan.step, plan.log, spec.lower,
                                       spec.upper, tie=plan.tie))
    return free_parameters(baseline_names(data, model), start, extra)


def true_angle_states(
    states: np.ndarray, model: ModelSpec, values: Mapping[str, float], dt_s: float
) -> np.ndarray:
    """Segment states of model ``model``, whose sensor reads through its causes, from states
    whose first column is the measured angle: the measured angle is kept (a few fixed-point
    steps through the measurement), the rate is not changed.  A sensor with memory (a lag)
    reads a segment's first sample as the model does, settled on the ramp of the state's
    rate over a sample period ``dt_s``; read as one series, it would carry every segment's
    state into the next."""
    out = states.copy()
    causes = model.causes
    if not has_measurement(causes):
        return out
    measured, rate = states[:, 0], states[:, 1]

    def first_sample(theta: np.ndarray) -> np.ndarray:
        if not measurement_has_memory(causes):
            return measured_angle(causes, values, np.zeros(theta.size), theta)
        t = np.array([0.0, dt_s])
        return np.array([measured_angle(causes, values, t, np.array([x, x + v * dt_s]), v)[0]
                         for x, v in zip(theta, rate, strict=True)])

    theta = measured.copy()
    for _ in range(4):
        theta = theta - (first_sample(theta) - measured)
    out[:, 0] = theta
    return out


def screen_cause(
    data: ForcedData, model: ModelSpec, ident: ForcedIdentification,
    hints: Mapping[str, float], threads: int | None,
) -> ShootingFit:
    """A model (the baseline, or the baseline extended by causes) fitted over the
    identification's short unlinked segments from
    where the identification started (equation error, priors, nominal contact values) and
    the hints on the cause's own parameters: every model is identified from the record the
    same way, and over segments this short a start far from the solution still converges.
    (Starting from the identification's solution instead would carry the compromises its
    own free barrier, sensor zero and phase made for an effect it lacks.)  The segments'
    states are drawn onto the data for each model: its own sensor and dynamics at its start
    values decide where they must begin."""
    timing = (q.drive_phase_rad, q.drive_frequency_hz) if not data.drive.timing_known else ()
    start = {k: v for k, v in ident.start.items() if k in BASELINE_PLANS or k in timing}
    free = candidate_parameters(data, model, start, record_scale(data, start),
                                level_hints(model, hints))
    fit, _ = fit_model(ForcedModel(data, model.causes), ident.short, free, {},
                       smoothed_states(data, ident.short.start, 0.0), threads=threads,
                       max_iterations=SCREEN_ITERATIONS)
    return fit


def fit_cause(
    data: ForcedData, model: ModelSpec, screened: ShootingFit, lay: Layouts,
    threads: int | None, seed: ShootingFit | None = None,
) -> ShootingFit:
    """A model fitted over the whole record from its screening fit's values.  Its segment
    states come from ``seed`` (a full-layout fit of another model that fits the record
    well, its states read through this model's sensor), or else are drawn onto the data
    over half-length segments first, as the identification does."""
    scale = record_scale(data, screened.values)
    free = [replace(p, start=screened.values[p.name]) for p in
            candidate_parameters(data, model, screened.values, scale, screened.values)]
    start_from = None
    if seed is not None:
        measured = seed.prediction[lay.full.start]
        states = true_angle_states(np.column_stack([measured, seed.states[:, 1]]), model,
                                   screened.values, data.dt)
        start_from = (replace(seed, states=states), lay.full)
    full, _ = fit_over_record(ForcedModel(data, model.causes), free, {}, threads=threads,
                              start_from=start_from,
                              max_iterations=REFINE_ITERATIONS)
    return full


def extend(data: ForcedData, parent: ModelSpec, parent_fit: ShootingFit,
           cause_name: str | None,
           segments: Segments, threads: int | None,
           max_iterations: int = REFINE_ITERATIONS) -> ShootingFit:
    """Model ``parent`` extended by ``cause_name``, fitted over ``segments`` (the layout of
    ``parent_fit``) from the parent's own solution with the new cause (nearly) neutral: it
    ends about as close to the record as the parent or closer (a nested model from its
    parent's optimum).  From the baseline it is the fallback when a fit from the cause's screening
    values ends in a worse basin (chaotic records have many); from a model with causes, it
    is a step of the forward selection.  ``cause_name`` None continues the parent itself
    for as many iterations: the fair yardstick of a step (a gain the parent would have
    made by iterating on is not the new cause's)."""
    model = parent.plus(cause_name) if cause_name else parent
    scale = record_scale(data, parent_fit.values)
    # the new cause at its plan's start: neutral, or next to it where the neutral value
    # gives the fit no gradient (a lag of 0, a second harmonic of 0 with its phase)
    neutral: dict[str, float] = {}
    if cause_name:
        neutral = {k: plan.start for k, plan in plan_for(cause(cause_name), scale).items()}
    start = {**parent_fit.values, **neutral}
    free = [replace(p, start=start[p.name])
            for p in candidate_parameters(data, model, start, scale, neutral)]
    states = true_angle_states(
        np.column_stack([parent_fit.prediction[segments.start], parent_fit.states[:, 1]]),
        model, start, data.dt)
    out, _ = fit_model(ForcedModel(data, model.causes), segments, free, {}, states,
                       warm_states=False, threads=threads, max_iterations=max_iterations)
    return out


def refit(data: ForcedData, model: ModelSpec, fit: ShootingFit, lay: Layouts,
          threads: int | None, *, heldout_s: float = 0.0,
          max_iterations: int = REFINE_ITERATIONS) -> ShootingFit:
    """Continue a full-layout fit (to convergence), or fit the training stretches
    (``heldout_s`` > 0) from it: the same free parameters, started at its solution."""
    scale = record_scale(data, fit.values)
    free = [replace(p, start=fit.values[p.name])
            for p in candidate_parameters(data, model, fit.values, scale, fit.values)]
    out, _ = fit_over_record(ForcedModel(data, model.causes), free, {}, heldout_s=heldout_s,
                             threads=threads,
                             start_from=(fit, lay.full), max_iterations=max_iterations)
    return out
