"""The discrepancy analysis of a forced record, on its own.

The record is identified first (:mod:`analysis.identify.forced`: equation-error start,
multiple shooting).  The baseline model of docs/MODEL.md section 2 (barrier at 0, sensor zero
at the hanging position, the stated table amplitude as a pure sine at the measured
frequency and phase) is then fitted by multiple shooting over the whole record, and so is
every candidate cause, each starting from the baseline's solution and from what the
identification and the table channel say about its parameters.

Two judges must agree that a cause earns its place (:mod:`analysis.discrepancy.selection`):
the information criterion of the fit over the whole record, and the forecast: the model
fitted on alternating stretches predicts the stretch after each from the state fitted
just before it, several drive periods ahead.  A chaotic record cannot be forecast that
far, so there the second judge is the invariant statistics of the model's own long run
against the record's (:mod:`analysis.discrepancy.invariants`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from analysis.discrepancy.candidates import (
    REPLACES,
    RecordScale,
    candidates_for,
    excluded_for,
    plan_for,
)
from analysis.discrepancy.fitting import FitData, FitResult
from analysis.discrepancy.invariants import Invariants, invariant_distance, invariants
from analysis.discrepancy.localize import localize
from analysis.discrepancy.outcome import Analysis, AnalysisError, CandidateOutcome
from analysis.discrepancy.selection import (
    BIC_MARGIN,
    Verdict,
    choose,
    information_criterion_delta,
)
from analysis.dynamics.measured_regime import judge_record_regime
from analysis.dynamics.regime import Regime
from analysis.experiments import FORCED
from analysis.extensions import NONE, cause
from analysis.identify.forced import (
    BASELINE_PLANS,
    SEGMENT_S,
    ForcedData,
    ForcedIdentification,
    ForcedModel,
    clock_parameter,
    fit_model,
    fit_over_record,
    forced_data,
    free_parameters,
    hertz_penetration_rad,
    identify_forced,
    impact_speed,
    record_segments,
    smoothed_states,
)
from analysis.identify.result import IdentificationError
from analysis.identify.shooting import FreeParameter, Segments, ShootingFit
from analysis.model_values import measured_angle, packed_from_values
from analysis.records import Record
from analysis.simulate import simulate_packed

HELDOUT_S = SEGMENT_S  # each fitted stretch is followed by a forecast one as long
MODEL_INVARIANT_SPAN = 4  # a model's invariants come from a run this many records long
SCREEN_ITERATIONS = 20  # every candidate, over short segments, from the cold start
# Over the record every model starts from its screening solution: a right one converges in
# a few iterations, a wrong one crawls, and more of its crawl would change no judgement.
REFINE_ITERATIONS = 12
REFINED = 4  # candidates refined beyond the screening (those that gained), best first
SEED_RMS = 3.0  # a full fit within this many noise levels lends its segment states

Progress = Callable[[str], None]


@dataclass(frozen=True)
class ModelFits:
    """One model fitted to the whole record and (when it is judged on forecasts) to the
    alternating training stretches."""

    cause: str
    full: ShootingFit
    train: ShootingFit | None = None


@dataclass(frozen=True)
class Layouts:
    """The two ways the record is cut: linked segments over everything, and alternating
    fitted and forecast stretches (their starts are every other segment's start)."""

    full: Segments
    train: Segments


def layouts(data: ForcedData) -> Layouts:
    """Segments of SEGMENT_S over the record; training stretches of SEGMENT_S, each
    followed by HELDOUT_S of forecast."""
    return Layouts(record_segments(data), record_segments(data, SEGMENT_S, HELDOUT_S))


def fit_data_view(data: ForcedData) -> FitData:
    """The forced record as the shared report and localisation code sees a record."""
    return FitData(
        experiment=FORCED.name, t=data.t, y=data.y, valid=data.valid, noise_rad=data.noise_rad,
        rig=data.rig, drive=data.drive.model_drive(), barrier=True,
        phase0_rad=data.drive.phase0_rad,
    )


def as_fit_result(fit: ShootingFit, cause_name: str, contacts: int = 0) -> FitResult:
    """A shooting fit as the judges and reports of every experiment see a fit."""
    return FitResult(
        cause=cause_name, values=dict(fit.values), estimates=dict(fit.estimates),
        residual=fit.residual, n_params=fit.n_params, success=fit.success,
        message=fit.message, contacts=contacts,
    )


def record_scale(data: ForcedData, values: Mapping[str, float]) -> RecordScale:
    """Magnitudes that size the candidates' steps and start values."""
    omega = values["omega_rad_s"]
    L = data.rig.g_m_s2 / omega**2
    level = float(np.nanmax(data.y))
    speed = impact_speed(data, level)
    K = values.get("K_N_per_m1.5", data.rig.K_N_per_m1_5)
    return RecordScale(
        amplitude_rad=float(np.nanmax(np.abs(data.y))), omega_rad_s=omega, zeta=values["zeta"],
        duration_s=float(data.t[-1]), dt_s=data.dt, inertia_kg_m2=data.rig.m_kg * L**2,
        stiffness=K, mu0_s_per_m=values.get("mu0_s_per_m", data.rig.mu0_s_per_m),
        penetration_m=data.rig.l_m * hertz_penetration_rad(data.rig, omega, K, speed),
    )


def cause_hints(ident: ForcedIdentification) -> dict[str, float]:
    """What the record says about the causes' parameters before any cause is fitted: the
    identified barrier and sensor zero, the table channel's amplitude and harmonic (or the
    identified amplitude when there is no table channel)."""
    values = ident.values
    hints = {"theta_b_rad": values["theta_b_rad"], "offset_rad": values["offset_rad"]}
    drive = ident.data.drive
    if drive.phase_known:
        # a sensor lagging by tau reads the response the drive caused Omega tau earlier
        delay = -math.remainder(values["drive_phase_rad"] - drive.phase0_rad, 2 * math.pi) \
            / drive.omega_rad_s
        if delay > 0:
            hints["tau_s"] = delay
    if drive.table is not None:
        hints["eps"] = drive.table.amplitude_m.value / drive.stated_amplitude_m - 1.0
        hints["h2"] = drive.table.h2.value
        hints["phi2_rad"] = drive.table.phi2_rad.value
    elif "eps" in values:
        hints["eps"] = values["eps"]
    return hints


def baseline_names(data: ForcedData, cause_name: str) -> list[str]:
    """The baseline parameters a fit adjusts (a cause may take over one's role)."""
    replaced = REPLACES.get(cause_name, ())
    return [n for n in BASELINE_PLANS if n not in replaced]


def candidate_parameters(
    data: ForcedData, cause_name: str, start: Mapping[str, float], scale: RecordScale,
    hints: Mapping[str, float],
) -> list[FreeParameter]:
    """Free parameters of the baseline extended by ``cause_name``."""
    extra = []
    if not data.drive.timing_known:
        extra.append(clock_parameter(start["drive_frequency_hz"]))
        phase = start["drive_phase_rad"]
        extra.append(FreeParameter("drive_phase_rad", phase, 1e-5, False, phase - math.pi,
                                   phase + math.pi))
    if cause_name != NONE:
        c = cause(cause_name)
        plans = plan_for(c, scale)
        for spec in c.parameters:
            plan = plans[spec.name]
            value = hints.get(spec.name, start.get(spec.name, plan.start))
            value = min(max(value, spec.lower), spec.upper)
            if plan.log:
                value = max(value, spec.lower if spec.lower > 0 else 1e-12)
            extra.append(FreeParameter(spec.name, value, plan.step, plan.log, spec.lower,
                                       spec.upper))
    return free_parameters(baseline_names(data, cause_name), start, extra)


def true_angle_states(
    states: np.ndarray, cause_name: str, values: Mapping[str, float]
) -> np.ndarray:
    """Segment states of a model whose sensor reads through ``cause_name``, from states of
    one that reads the angle directly: the measured angle is kept (a few fixed-point steps
    through the measurement), the rate is not changed."""
    out = states.copy()
    if cause_name == NONE or cause(cause_name).measurement is None:
        return out
    measured = states[:, 0]
    theta = measured.copy()
    for _ in range(4):
        seen = measured_angle((cause_name,), values, np.zeros(theta.size), theta)
        theta = theta - (seen - measured)
    out[:, 0] = theta
    return out


def screen_cause(
    data: ForcedData, cause_name: str, ident: ForcedIdentification,
    hints: Mapping[str, float], threads: int | None,
) -> ShootingFit:
    """A cause (or ``none``) fitted over the identification's short unlinked segments from
    where the identification started (equation error, priors, nominal contact values) and
    the hints on the cause's own parameters: every model is identified from the record the
    same way, and over segments this short a start far from the solution still converges.
    (Starting from the identification's solution instead would carry the compromises its
    own free barrier, sensor zero and phase made for an effect it lacks.)  The segments'
    states are drawn onto the data for each model: its own sensor and dynamics at its start
    values decide where they must begin."""
    model = ForcedModel(data, () if cause_name == NONE else (cause_name,))
    timing = ("drive_phase_rad", "drive_frequency_hz") if not data.drive.timing_known else ()
    start = {k: v for k, v in ident.start.items() if k in BASELINE_PLANS or k in timing}
    free = candidate_parameters(data, cause_name, start, record_scale(data, start), hints)
    fit, _ = fit_model(model, ident.short, free, {},
                       smoothed_states(data, ident.short.start, 0.0), threads=threads,
                       max_iterations=SCREEN_ITERATIONS)
    return fit


def fit_cause(
    data: ForcedData, cause_name: str, screened: ShootingFit, lay: Layouts,
    threads: int | None, seed: ShootingFit | None = None,
) -> ShootingFit:
    """A cause fitted over the whole record from its screening fit's values.  Its segment
    states come from ``seed`` (a full-layout fit of another model that fits the record
    well, its states read through this cause's sensor), or else are drawn onto the data
    over half-length segments first, as the identification does."""
    model = ForcedModel(data, () if cause_name == NONE else (cause_name,))
    scale = record_scale(data, screened.values)
    free = [replace(p, start=screened.values[p.name]) for p in
            candidate_parameters(data, cause_name, screened.values, scale, screened.values)]
    start_from = None
    if seed is not None:
        measured = seed.prediction[lay.full.start]
        states = true_angle_states(np.column_stack([measured, seed.states[:, 1]]), cause_name,
                                   screened.values)
        start_from = (replace(seed, states=states), lay.full)
    full, _ = fit_over_record(model, free, {}, threads=threads, start_from=start_from,
                              max_iterations=REFINE_ITERATIONS)
    return full


def refit(data: ForcedData, cause_name: str, fit: ShootingFit, lay: Layouts,
          threads: int | None, *, heldout_s: float = 0.0,
          max_iterations: int = REFINE_ITERATIONS) -> ShootingFit:
    """Continue a full-layout fit (to convergence), or fit the training stretches
    (``heldout_s`` > 0) from it: the same free parameters, started at its solution."""
    model = ForcedModel(data, () if cause_name == NONE else (cause_name,))
    scale = record_scale(data, fit.values)
    free = [replace(p, start=fit.values[p.name])
            for p in candidate_parameters(data, cause_name, fit.values, scale, fit.values)]
    out, _ = fit_over_record(model, free, {}, heldout_s=heldout_s, threads=threads,
                             start_from=(fit, lay.full), max_iterations=max_iterations)
    return out


def model_invariants_distance(
    data: ForcedData, measured: Invariants, cause_name: str, fit: ShootingFit
) -> float:
    """Distance between the record's invariants and those of the fitted model run from its
    first segment's state over MODEL_INVARIANT_SPAN times the record's length."""
    causes = () if cause_name == NONE else (cause_name,)
    values = fit.values
    phase = values.get("drive_phase_rad", data.drive.phase0_rad)
    drive = data.drive.model_drive(values.get("drive_frequency_hz"))
    p = packed_from_values(data.rig, drive, True, values, causes, phase)
    n = MODEL_INVARIANT_SPAN * data.t.size
    sim = simulate_packed(p, float(fit.states[0, 0]), float(fit.states[0, 1]), n * data.dt,
                          1.0 / data.dt, poincare_phase=None, rtol=1e-8, atol=1e-10)
    t = np.arange(sim.theta.size) * data.dt
    theta = measured_angle(causes, values, t, np.asarray(sim.theta, dtype=float))
    if theta.size < 16:
        return math.inf
    return invariant_distance(measured, invariants(t, theta, data.drive.frequency_hz, phase))


def forecast_z(base: ShootingFit, candidate: ShootingFit, train: Segments) -> float | None:
    """The drop of the mean-square forecast error from baseline to candidate, in standard
    errors of its mean over the held-out stretches (a paired test: the same noise enters
    both, so small real gains show)."""
    gains = []
    for a, b in zip(train.fit_stop, train.stop, strict=True):
        rb, rc = base.forecast_residual[a:b], candidate.forecast_residual[a:b]
        both = np.isfinite(rb) & np.isfinite(rc)
        if np.count_nonzero(both) >= 2:
            gains.append(float(np.mean(rb[both] ** 2) - np.mean(rc[both] ** 2)))
    if len(gains) < 3:
        return None
    g = np.asarray(gains)
    spread = float(np.std(g, ddof=1)) / math.sqrt(g.size)
    if not spread > 0:
        return math.inf if g.mean() > 0 else -math.inf
    return float(g.mean() / spread)


def verdict_of(
    data: ForcedData, candidate: ModelFits, base: ModelFits, lay: Layouts,
    distances: tuple[float | None, float | None] = (None, None),
    not_judged: str | None = None,
) -> Verdict:
    """Both judges' view of a candidate against the baseline (without training fits, when
    it did not pass the information criterion or a better cause was accepted first, it has
    no forecast)."""
    judged = candidate.train is not None and base.train is not None
    return Verdict(
        cause=candidate.cause,
        information_criterion_delta=information_criterion_delta(
            as_fit_result(base.full, NONE), as_fit_result(candidate.full, candidate.cause),
            data.noise_rad),
        heldout_rms_baseline=base.train.forecast_rms if base.train is not None else math.nan,
        heldout_rms_extended=candidate.train.forecast_rms if judged else math.nan,
        rms_baseline=base.full.rms,
        rms_extended=candidate.full.rms,
        invariant_distance_baseline=distances[0],
        invariant_distance_extended=distances[1],
        noise_rad=data.noise_rad,
        n_heldout=int(np.count_nonzero(np.isfinite(base.train.forecast_residual)))
        if base.train is not None else 0,
        forecast_z=forecast_z(base.train, candidate.train, lay.train) if judged else None,
        not_judged=not_judged,
    )


@dataclass
class ForcedOutcome:
    """What the forced path found, before it becomes the shared report."""

    data: ForcedData
    ident: ForcedIdentification
    base: ModelFits
    candidates: list[tuple[ModelFits, Verdict]]
    chaotic: bool
    timings: dict[str, float]
    notes: list[str]


def analyze_forced_fits(
    record_or_data, *, priors: Mapping[str, float] | None = None,
    causes: Sequence[str] | None = None, chaotic: bool = False,
    progress: Progress | None = None, threads: int | None = None,
) -> ForcedOutcome:
    """Identify, fit the baseline and every candidate, judge them.

    Every candidate is fitted for SCREEN_ITERATIONS; the REFINED best (by the information
    criterion) and any other that already passes it are fitted to convergence; the ones
    that pass are then fitted to the training stretches for the forecast judge (or, on a
    chaotic record, run long for the invariant statistics).
    """
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    timings: dict[str, float] = {}
    data = record_or_data if isinstance(record_or_data, ForcedData) else \
        forced_data(record_or_data)
    ident = identify_forced(data, priors=priors, progress=say, threads=threads, whole=False)
    timings["identification"] = time.perf_counter() - clock
    notes = list(ident.notes)
    lay = layouts(data)
    hints = cause_hints(ident)
    names = [c.name for c in candidates_for(FORCED.name)]
    if causes is not None:
        names = [n for n in names if n in causes]
    say(f"screening every cause over {ident.short.count} short segments")
    screened = {n: screen_cause(data, n, ident, hints, threads) for n in [NONE, *names]}
    base_short = ModelFits(NONE, screened[NONE])
    bic = {n: _bic(data, base_short, screened[n]) for n in names}
    say("screened: " + ", ".join(f"{n} {bic[n]:.3g}" for n in sorted(bic, key=lambda n: -bic[n])))
    timings["screening"] = time.perf_counter() - clock - timings["identification"]
    say("fitting the baseline model over the record")
    base_full = fit_cause(data, NONE, screened[NONE], lay, threads)
    base = ModelFits(NONE, base_full)
    say(f"baseline rms {base_full.rms:.3g} rad ({base_full.rms / data.noise_rad:.3g} x noise)")
    ranked = sorted(names, key=lambda n: -bic[n])
    fits: dict[str, ShootingFit] = {}
    for name in [n for n in ranked if bic[n] > 0.0][:REFINED]:
        # the best full fit so far lends its states when it fits the record closely
        best = min([base_full, *fits.values()], key=lambda f: f.rms)
        seed = best if best.rms < SEED_RMS * data.noise_rad else None
        fits[name] = fit_cause(data, name, screened[name], lay, threads, seed)
        bic[name] = _bic(data, base, fits[name])
        say(f"  {name} over the record: BIC gain {bic[name]:.3g}")
    for name in names:
        if name not in fits:  # judged on its screening: it did not come close
            bic[name] = min(bic[name], BIC_MARGIN)
    # The judges, best information criterion first: forecasts over the training stretches
    # (and, on a chaotic record, the invariant statistics of the model's own long run); the
    # first cause they accept is the finding, and the rest need no training fits.
    passing = sorted((n for n in names if bic[n] > BIC_MARGIN), key=lambda n: -bic[n])
    measured = base_distance = None
    if passing:
        base = ModelFits(NONE, base_full, refit(data, NONE, base_full, lay, threads,
                                                heldout_s=HELDOUT_S))
        if chaotic:
            measured = invariants(data.t, data.y, data.drive.frequency_hz,
                                  data.drive.phase0_rad)
            base_distance = model_invariants_distance(data, measured, NONE, base_full)
    judged: dict[str, Verdict] = {}
    trains: dict[str, ShootingFit] = {}
    accepted = None
    for name in passing:
        if accepted is not None:
            judged[name] = verdict_of(
                data, ModelFits(name, fits[name]), base, lay,
                not_judged=f"not judged further: {accepted} scores higher and earns its place")
            continue
        distances: tuple[float | None, float | None] = (None, None)
        if chaotic:
            distances = (base_distance,
                         model_invariants_distance(data, measured, name, fits[name]))
        trains[name] = refit(data, name, fits[name], lay, threads, heldout_s=HELDOUT_S)
        judged[name] = verdict_of(data, ModelFits(name, fits[name], trains[name]), base, lay,
                                  distances)
        if judged[name].earns_keep:
            accepted = name
    outcomes = []
    for name in names:
        model_fits = ModelFits(name, fits.get(name, screened[name]), trains.get(name))
        verdict = judged.get(name) or verdict_of(
            data, model_fits, base if name in fits else base_short, lay)
        say(f"  {name}: {verdict.why}")
        outcomes.append((model_fits, verdict))
    timings["fits"] = time.perf_counter() - clock - sum(timings.values())
    return ForcedOutcome(data, ident, base, outcomes, chaotic, timings, notes)


def _bic(data: ForcedData, base: ModelFits, fit: ShootingFit) -> float:
    return information_criterion_delta(as_fit_result(base.full, NONE),
                                       as_fit_result(fit, "candidate"), data.noise_rad)


def regime_of(record: Record, data: ForcedData) -> Regime:
    """The record's regime judged from its strobe points (on the tach, else on the measured
    drive), aware of its noise; 'undetermined', with the reason, when the record cannot be
    judged (too few drive periods, say)."""
    drive = data.drive
    try:
        regime, _ = judge_record_regime(
            np.asarray(record.angle_rad, dtype=float), record.sample_rate_hz, data.noise_rad,
            tach_indices=record.tach_indices if drive.clock is not None else None,
            frequency_hz=drive.frequency_hz, phase_rad=drive.phase0_rad,
        )
    except ValueError as error:
        return Regime("undetermined", None, f"undetermined: {error}")
    return regime


def regime_summary(regime: Regime) -> dict[str, Any]:
    """The regime for the report: kind, period, label and the evidence a reader checks."""
    keep = ("transient_periods", "transient_s", "periods_in_record", "tolerance_rad", "K",
            "lyapunov_per_period", "subharmonics", "superharmonics", "incommensurate")
    return {"kind": regime.kind, "period": regime.period, "label": regime.label,
            "evidence": {k: regime.evidence[k] for k in keep if k in regime.evidence}}


def analyze_forced(
    record: Record, *, priors: Mapping[str, float] | None = None,
    causes: Sequence[str] | None = None, progress: Progress | None = None,
    threads: int | None = None,
) -> Analysis:
    """The discrepancy analysis of a forced record (see the module's docstring)."""
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    try:
        data = forced_data(record)
    except IdentificationError as error:
        raise AnalysisError(f"{record.source or 'record'}: {error}") from error
    regime = regime_of(record, data)
    chaotic = regime.kind == "chaotic"
    say(f"forced: {data.n_valid} samples at {1 / data.dt:.4g} Hz, noise {data.noise_rad:.3g} "
        f"rad, drive {data.drive.frequency_hz:.6g} Hz ({data.drive.frequency_source}); "
        f"regime {regime.label}")
    judge_time = time.perf_counter() - clock
    try:
        out = analyze_forced_fits(data, priors=priors, causes=causes, chaotic=chaotic,
                                  progress=say, threads=threads)
    except IdentificationError as error:
        raise AnalysisError(f"{record.source or 'record'}: {error}") from error
    verdict = choose([v for _, v in out.candidates])
    chosen = verdict.cause if verdict is not None else NONE
    base = out.base
    view = fit_data_view(data)
    baseline = as_fit_result(base.full, NONE)
    candidates = [
        CandidateOutcome(
            cause=fits.cause,
            train=as_fit_result(fits.train if fits.train is not None else fits.full, fits.cause),
            full=as_fit_result(fits.full, fits.cause),
            verdict=v,
            prediction=(fits.train if fits.train is not None else fits.full).prediction,
        )
        for fits, v in out.candidates
    ]
    in_contact = base.full.true_angle > 0.0
    localization = localize(view, baseline, base.full.rate, _widened(in_contact))
    shown = next((f for f, _ in out.candidates if f.cause == chosen), None)
    if shown is None and out.candidates:
        shown = max(out.candidates, key=lambda fv: fv[1].information_criterion_delta)[0]
    notes = [*out.notes]
    if chaotic:
        notes.append("chaotic response: the causes are judged on the invariant statistics "
                     "of the model's own long run (Poincare section, turning points, spectral "
                     "lines), not on forecasts")
    timings = {"regime": judge_time, **out.timings, "total": time.perf_counter() - clock}
    say(f"cause: {chosen} ({timings['total']:.1f} s)")
    return Analysis(
        record=record, data=view, n_train=view.t.size,
        baseline_train=as_fit_result(base.train if base.train is not None else base.full, NONE),
        baseline=baseline, baseline_prediction=base.full.prediction, candidates=candidates,
        excluded=excluded_for(FORCED.name), chosen=chosen, localization=localization,
        zero_one_k=regime.evidence.get("K"), chaotic=chaotic, timings=timings, notes=notes,
        regime=regime_summary(regime), drive=data.drive.as_json(),
        baseline_heldout_rms=base.train.forecast_rms if base.train is not None else None,
        curves=(base.full.prediction, shown.full.prediction if shown is not None else None),
        heldout_description=(
            f"forecasts over the {HELDOUT_S:g} s after each fitted stretch of {SEGMENT_S:g} s, "
            "from the state fitted at that stretch's start"
        ),
    )


def _widened(mask: np.ndarray, guard: int = 2) -> np.ndarray:
    """``mask`` grown by ``guard`` samples either side."""
    out = mask.copy()
    for shift in range(1, guard + 1):
        out[shift:] |= mask[:-shift]
        out[:-shift] |= mask[shift:]
    return out
