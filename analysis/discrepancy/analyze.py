"""The discrepancy analysis of one record: baseline fit, where it fails, every candidate cause
fitted as an extension, the choice, and the report of docs/MODEL.md section 6.

Forced records go to :mod:`analysis.discrepancy.forced` (identification from the record
alone, multiple shooting, forecasts or invariant statistics).  Decays are fitted point by
point here: the baseline starts from ``analysis.identify``'s estimates, every candidate
from the baseline's solution with its cause neutral.  Each model is fitted on the first
part of the record (to predict the rest) and then on the whole record (parameters,
intervals, information criterion).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.candidates import candidates_for, excluded_for
from analysis.discrepancy.constancy import constancy_finding
from analysis.discrepancy.fitting import FitData, FitResult, fit, predict
from analysis.discrepancy.forced import analyze_forced
from analysis.discrepancy.forward import forward_selection
from analysis.discrepancy.forward import indistinct as forward_indistinct
from analysis.discrepancy.localize import localize, motion_of
from analysis.discrepancy.outcome import Analysis, AnalysisError, CandidateOutcome
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.residual_reading import Finding, read_residual
from analysis.discrepancy.restitution import fit_restitution, restitution_from_hunt_crossley
from analysis.discrepancy.selection import (
    Verdict,
    choose,
    heldout_rms,
    information_criterion_delta,
    paired_gain_z,
)
from analysis.discrepancy.term_proposal import ProposedTerm, propose_terms
from analysis.dynamics.lines import FALSE_ALARM
from analysis.extensions import BASELINE, NONE, ModelSpec, RecordScale, cause, implausibility
from analysis.identify import IdentificationError, fit_free_decay, fit_impact_decay
from analysis.identify.impact_decay import impact_events
from analysis.identify.preprocess import prepare
from analysis.identify.result import Estimate
from analysis.identify.threads import blas_on_one_thread
from analysis.model import Drive
from analysis.model_values import packed_from_values
from analysis.progress import ProgressText
from analysis.records import Record

MAX_FIT_SAMPLES = 4000
MAX_FIT_SAMPLES_WITH_CONTACT = 8000  # contacts last milliseconds: keep more samples


# --------------------------------------------------------------------------- preparation


def prepare_data(record: Record, *, thinned: bool = True) -> tuple[FitData, list[str]]:
    """The fit's view of a decay record: release and rest trimmed, bad samples out,
    decimated to at most MAX_FIT_SAMPLES samples (unless not ``thinned``: every sample),
    noise level from the full-rate data."""
    notes: list[str] = []
    kind = record.kind
    signal = prepare(record.time_s, record.angle_rad, detect_release=True)
    t, y, valid, noise = signal.time_s, signal.angle_rad, signal.valid, signal.noise_rad
    notes.extend(signal.notes)
    limit = MAX_FIT_SAMPLES_WITH_CONTACT if kind.barrier else MAX_FIT_SAMPLES
    stride = max(1, math.ceil(t.size / limit)) if thinned else 1
    if stride > 1:
        notes.append(f"fitted on one sample in {stride} ({t.size} -> {-(-t.size // stride)})")
    t, y, valid = t[::stride], y[::stride], valid[::stride].copy()
    data = FitData(
        experiment=record.experiment, t=t - t[0], y=y, valid=valid, noise_rad=float(noise),
        rig=record.rig_parameters(), drive=Drive(), barrier=kind.barrier,
    )
    return data, notes


def proposed_terms(record: Record, model: ModelSpec,
                   values: Mapping[str, float]) -> list[ProposedTerm]:
    """The terms the residual acceleration of a decay's final model (``model`` at
    ``values``) asks for
    (:mod:`analysis.discrepancy.term_proposal`), at every sample of the record (a contact
    lasts milliseconds) and at the data's true angle: the measured one with the model's
    sensor (its measured minus its true angle) taken off."""
    data, _ = prepare_data(record, thinned=False)
    measured, sim = predict(data, model, values)
    n = min(data.t.size, sim.theta.size)
    true = np.asarray(sim.theta, dtype=float)[:n]
    rate = np.asarray(sim.theta_dot, dtype=float)[:n]
    packed = packed_from_values(data.rig, data.drive, data.barrier, values, model.causes,
                                data.phase0_rad)
    theta = data.y[:n] - (measured[:n] - true)
    return propose_terms(data.t[:n], theta, data.valid[:n], packed, true, rate)


def decay_implausibility(model: ModelSpec, values: Mapping[str, float],
                         policy: SelectionPolicy) -> str | None:
    """Why a decay's model is no explanation a real rig can have: its causes' values
    (:func:`analysis.extensions.implausibility`), or causes that take all of the rig's
    viscous damping (zeta below ``policy.viscous_floor``).  A contact damping on delta^2
    was named dry friction, whose fit held zeta at 0, with nothing flagged."""
    reasons = [implausibility(model, values)]
    if model.causes and values.get(q.zeta, math.inf) < policy.viscous_floor:
        reasons.append(f"zeta = {values[q.zeta]:.3g}: the causes take all of the rig's "
                       f"viscous damping (below {policy.viscous_floor:g}), which air alone "
                       "gives a real pendulum")
    return "; ".join(r for r in reasons if r) or None


def implausible_gain_finding(outcomes: Sequence[CandidateOutcome]) -> Finding | None:
    """An ``implausible_gain`` finding when a candidate would earn its keep but its values are
    no real rig's (the record then names no cause): the record asks for something the named
    causes can only stand in for.  The candidate of largest information-criterion gain is
    named."""
    asked = [o for o in outcomes if o.verdict.earns_keep_but_implausible]
    if not asked:
        return None
    top = max(asked, key=lambda o: o.verdict.information_criterion_delta)
    v = top.verdict
    return Finding("implausible_gain", (
        f"{top.model} would explain the record (BIC gain "
        f"{v.information_criterion_delta:.3g}, held-out error x{v.heldout_ratio:.3g}) but is "
        f"no explanation a real rig can have: {v.implausible}; something outside the named "
        "causes is missing"), {"information_criterion_delta": v.information_criterion_delta,
                               "heldout_ratio": v.heldout_ratio})


def baseline_start(
    record: Record, data: FitData
) -> tuple[dict[str, float], dict[str, float], list[str]]:
    """Start values of the baseline fit from ``analysis.identify``, and hints: identified
    values of parameters the baseline holds (sensor zero, barrier position), which start
    the candidates that free them."""
    notes: list[str] = []
    if not data.barrier:
        result = fit_free_decay(record)
        hints = {q.offset_rad: result[q.offset_rad].value}
        fitted = result.details["fitted"]
        omega, zeta = result[q.omega_rad_s].value, result[q.zeta].value
        if q.theta_dot0_rad_s in fitted:
            theta_dot0 = float(fitted[q.theta_dot0_rad_s])
        else:
            a, ph = fitted["amplitude_rad"], fitted["phase_rad"]
            theta_dot0 = -a * omega * (math.sin(ph) + zeta * math.cos(ph))
        return {
            q.theta0_rad: result[q.theta0_rad].value, q.theta_dot0_rad_s: theta_dot0,
            q.omega_rad_s: omega, q.zeta: zeta,
        }, hints, notes
    if data.barrier:
        try:
            result = fit_impact_decay(record)
        except (OverflowError, FloatingPointError) as error:
            # identify's interval arithmetic can overflow on a poorly determined K; its
            # impact-by-impact first estimate still gives a start
            notes.append(f"identification failed ({error}); started from the impact events")
            return (*_impact_events_start(record, data), notes)
        hints = {q.offset_rad: result[q.offset_rad].value,
                 q.theta_b_rad: result[q.theta_b_rad].value}
        fitted = result.details["fitted"]
        omega = data.rig.g_m_s2 / result[q.L_m].value
        return {
            q.theta0_rad: float(fitted[q.theta0_rad]),
            q.theta_dot0_rad_s: float(fitted[q.theta_dot0_rad_s]),
            q.omega_rad_s: math.sqrt(omega), q.zeta: result[q.zeta].value,
            q.K_N_per_m1_5: result[q.K_N_per_m1_5].value,
            q.mu0_s_per_m: max(result[q.mu0_s_per_m].value, 1e-3),
        }, hints, notes
    raise AnalysisError(f"{record.experiment}: not a decay record")


def _impact_events_start(
    record: Record, data: FitData
) -> tuple[dict[str, float], dict[str, float]]:
    """Start values from the free flights between impacts (identify's first estimate)."""
    signal = prepare(record.time_s, record.angle_rad, detect_release=True)
    rig = data.rig
    events = impact_events(signal, rig)
    good = np.flatnonzero(signal.valid[:5])
    y = signal.angle_rad - events[q.offset_rad]
    theta_dot0 = float(np.polyfit(signal.time_s[good], y[good], 1)[0]) if good.size > 1 else 0.0
    start = {
        q.theta0_rad: float(y[good[0]]), q.theta_dot0_rad_s: theta_dot0,
        q.omega_rad_s: float(events[q.omega_rad_s]), q.zeta: 0.005,
        q.K_N_per_m1_5: float(events["K"]), q.mu0_s_per_m: max(float(events["mu0"]), 1e-3),
    }
    hints = {q.offset_rad: float(events[q.offset_rad]), q.theta_b_rad: float(events[q.theta_b_rad])}
    return start, hints


def priors_from_decays(
    free_decay: Record | None = None, impact_decay: Record | None = None
) -> dict[str, float]:
    """Model values identified from the rig's decay records, to start a forced-record fit."""
    priors: dict[str, float] = {}
    if free_decay is not None:
        result = fit_free_decay(free_decay)
        priors.update(omega_rad_s=result[q.omega_rad_s].value, zeta=result[q.zeta].value)
    if impact_decay is not None:
        hold = {q.L_m: free_decay and result[q.L_m].value, q.zeta: priors.get(q.zeta)}
        result = fit_impact_decay(
            impact_decay, hold={k: v for k, v in hold.items() if v}
        )
        priors[q.K_N_per_m1_5] = result[q.K_N_per_m1_5].value
        priors[q.mu0_s_per_m] = result[q.mu0_s_per_m].value
        priors[q.theta_b_rad] = result[q.theta_b_rad].value
        priors[q.offset_rad] = result[q.offset_rad].value
        if q.omega_rad_s in result.parameters:
            priors.setdefault(q.omega_rad_s, result[q.omega_rad_s].value)
        priors.setdefault(q.zeta, result[q.zeta].value)
    return priors


# --------------------------------------------------------------------------- candidates


@dataclass(frozen=True)
class DecayFits:
    """What every fit of a decay shares: the prepared record, its training part, the scale
    of its steps, the identified hints on causes' parameters (and the identification's whole
    solution, a second start where a cause frees one of them) and the rules."""

    data: FitData
    n_train: int
    scale: RecordScale
    hints: Mapping[str, float]
    identified: Mapping[str, float]
    policy: SelectionPolicy

    @property
    def head(self) -> FitData:
        """The training part: the record's first ``n_train`` samples."""
        return self.data.head(self.n_train / self.data.t.size)

    def heldout_error(self, prediction: np.ndarray) -> np.ndarray:
        """A training fit's prediction minus the data on the held-out part (NaN elsewhere)."""
        use = self.data.valid.copy()
        use[:self.n_train] = False
        return np.where(use, prediction - np.where(use, self.data.y, 0.0), np.nan)

    def paired_z(self, against: np.ndarray, prediction: np.ndarray) -> float | None:
        """The held-out judge's paired test of ``prediction`` against ``against``, block by
        block over the held-out part (:func:`paired_gain_z`)."""
        edges = np.linspace(self.n_train, self.data.t.size,
                            self.policy.heldout_blocks + 1).astype(int)
        return paired_gain_z(self.heldout_error(against), self.heldout_error(prediction),
                             pairwise(edges))


def assess_candidate(
    model: ModelSpec, fits: DecayFits, start: FitResult, against: FitResult,
    against_prediction: np.ndarray, *, rival: bool = True,
) -> CandidateOutcome:
    """Fit ``model`` on the training part from ``start``'s training solution (the causes it
    lacks neutral), predict the rest, fit the whole record, and judge it against
    ``against`` (the baseline, or in a forward step the model it extends by one cause) whose
    training fit predicts ``against_prediction``: the information criterion over the
    record, and the prediction of the rest (its error, and a paired test block by block).
    With ``rival``, a model that earns its keep also refits ``start``'s model from its
    solution: is the gain the cause's, or only a better basin of the baseline's own
    parameters?"""
    data, head = fits.data, fits.head
    own = {s.name for c in model.causes for s in cause(c).parameters}
    hinted = {k: v for k, v in fits.hints.items() if k in own}
    train = fit(head, model, start.values, fits.scale)
    if hinted:
        # The identification fitted this parameter together with the baseline's: its
        # whole solution is a second start, often in another basin than the baseline's.
        second = fit(head, model, {**fits.identified, **hinted}, fits.scale)
        if second.rms < train.rms:
            train = second
    prediction, _ = predict(data, model, train.values)
    full = fit(data, model, train.values, fits.scale)
    verdict = Verdict(
        model=model,
        information_criterion_delta=information_criterion_delta(against, full, data.noise_rad),
        heldout_rms_baseline=heldout_rms(against_prediction, data.y, data.valid, fits.n_train),
        heldout_rms_extended=heldout_rms(prediction, data.y, data.valid, fits.n_train),
        forecast_z=fits.paired_z(against_prediction, prediction),
        rms_baseline=against.rms,
        rms_extended=full.rms,
        noise_rad=data.noise_rad,
        n_heldout=int(np.count_nonzero(data.valid[fits.n_train:])),
        implausible=decay_implausibility(model, full.values, fits.policy),
        policy=fits.policy,
    )
    better_basin = None
    if rival and verdict.earns_keep:
        keys = set(start.values)
        refit = fit(head, start.model, {k: v for k, v in train.values.items() if k in keys},
                    fits.scale)
        if refit.rms < start.rms * (1.0 - 1e-3):
            better_basin = refit
    return CandidateOutcome(model, train, full, verdict, prediction, better_basin)


def rejudge(
    outcome: CandidateOutcome, baseline: FitResult, baseline_prediction: np.ndarray,
    fits: DecayFits,
) -> CandidateOutcome:
    """The same candidate judged against a new baseline fit (whose training fit predicts
    ``baseline_prediction``)."""
    data = fits.data
    verdict = replace(
        outcome.verdict,
        information_criterion_delta=information_criterion_delta(
            baseline, outcome.full, data.noise_rad
        ),
        heldout_rms_baseline=heldout_rms(baseline_prediction, data.y, data.valid,
                                         fits.n_train),
        forecast_z=fits.paired_z(baseline_prediction, outcome.prediction),
        rms_baseline=baseline.rms,
    )
    return replace(outcome, verdict=verdict, rival=None)


@dataclass(frozen=True)
class _Assessment:
    """One :func:`assess_candidate` call, as a process pool's job."""

    model: ModelSpec
    start: FitResult
    against: FitResult
    against_prediction: np.ndarray
    rival: bool = True


def _assess_job(args: tuple[DecayFits, _Assessment]) -> CandidateOutcome:
    fits, job = args
    return assess_candidate(job.model, fits, job.start, job.against, job.against_prediction,
                            rival=job.rival)


def _assessed(fits: DecayFits, jobs: list[_Assessment], pool: Executor | None
              ) -> list[CandidateOutcome]:
    """Each job's outcome, in order: in ``pool``'s processes when there is a pool and more
    than one job."""
    work = [(fits, job) for job in jobs]
    if pool is not None and len(work) > 1:
        return list(pool.map(_assess_job, work))
    return list(map(_assess_job, work))


class DecaySteps:
    """The forward selection's steps on a decay (:mod:`analysis.discrepancy.forward`),
    point by point: a cause is screened beside the current model by fitting it from the
    current model's training solution (the step's nested fit, judged on the held-out part
    after the training one), and the best are fitted again afresh, from the baseline's
    training solution with every cause of the model neutral, the closer over the record
    kept.  A decay's fits run to convergence, so the current model itself is the step's
    yardstick."""

    def __init__(self, fits: DecayFits, baseline_train: FitResult,
                 outcomes: Sequence[CandidateOutcome], pool: Executor | None) -> None:
        self.fits, self.baseline_train, self.pool = fits, baseline_train, pool
        self.single = {o.model.causes[0]: o for o in outcomes}
        self.beside: dict[str, CandidateOutcome] = {}

    def open_structure(self, current: CandidateOutcome) -> str | None:
        data = self.fits.data
        left = read_residual(data.t, current.full.residual, data.valid, data.noise_rad)
        if left.structured or left.ljung_box_p < FALSE_ALARM:
            return None
        return (f"{left.why}, and its correlation is no more than white noise's (Ljung-Box "
                f"p {left.ljung_box_p:.2g})")

    def screen(self, current: CandidateOutcome) -> dict[str, float]:
        jobs = [_Assessment(current.model.plus(name), current.train, current.full,
                            current.prediction, rival=False)
                for name in self.single if name not in current.model.causes]
        self.beside = {o.model.causes[-1]: o for o in _assessed(self.fits, jobs, self.pool)}
        return {name: o.verdict.information_criterion_delta for name, o in self.beside.items()}

    def refused(self, current: CandidateOutcome, name: str) -> str | None:
        return None  # a decay has no channel that measures a cause apart from the angle

    def fit(self, current: CandidateOutcome, names: Sequence[str]
            ) -> tuple[CandidateOutcome, dict[str, CandidateOutcome]]:
        jobs = [_Assessment(current.model.plus(name), self.baseline_train, current.full,
                            current.prediction, rival=False)
                for name in names]
        afresh = _assessed(self.fits, jobs, self.pool)
        return current, {name: min(self.beside[name], again, key=lambda o: o.full.rss)
                         for name, again in zip(names, afresh, strict=True)}

    def gain(self, parent: CandidateOutcome, fit: CandidateOutcome) -> float:
        return information_criterion_delta(parent.full, fit.full, self.fits.data.noise_rad)

    def disqualification(self, model: ModelSpec, fit: CandidateOutcome) -> str | None:
        return decay_implausibility(model, fit.full.values, self.fits.policy)

    def estimates(self, fit: CandidateOutcome) -> Mapping[str, Estimate]:
        return fit.full.estimates

    def full(self, fitted: CandidateOutcome) -> CandidateOutcome:
        return fitted

    def judge(self, current: CandidateOutcome, parent: CandidateOutcome, model: ModelSpec,
              fit: CandidateOutcome) -> tuple[CandidateOutcome, Verdict]:
        return fit, fit.verdict  # judged against the current model when it was fitted

    def adopted(self, fitted: CandidateOutcome, name: str | None) -> None:
        return None

    def alone(self, model: ModelSpec) -> CandidateOutcome | None:
        return self.single.get(model.causes[0]) if len(model.causes) == 1 else None


def analyze_record(
    record: Record, *, workers: int | None = None, progress: ProgressText | None = None,
    causes: list[str] | None = None, priors: Mapping[str, float] | None = None,
    policy: SelectionPolicy = DEFAULT_POLICY,
) -> Analysis:
    """Run the whole discrepancy analysis on one record.

    ``priors`` start the model values of a forced record (see :func:`priors_from_decays`);
    ``causes`` restricts the candidates (default: every cause that can show); ``workers``
    processes fit a decay's candidates (a forced record's fits use that many threads);
    ``policy`` holds every rule that decides what is named (the report states it).
    """
    workers = workers if workers is not None else min(2, os.cpu_count() or 1)
    if record.kind.driven:
        return analyze_forced(record, priors=priors, causes=causes, progress=progress,
                              threads=workers, policy=policy)
    return analyze_decay(record, workers=workers, progress=progress, causes=causes,
                         policy=policy)


def analyze_decay(
    record: Record, *, workers: int = 1, progress: ProgressText | None = None,
    causes: list[str] | None = None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> Analysis:
    """The discrepancy analysis of a free or impact decay, point by point."""
    blas_on_one_thread()
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    timings: dict[str, float] = {}
    data, notes = prepare_data(record)
    if data.n_valid < 50:
        raise AnalysisError(f"{record.source or 'record'}: only {data.n_valid} usable samples")
    say(f"{data.experiment}: {data.n_valid} samples at {1 / data.dt:.4g} Hz, "
        f"noise {data.noise_rad:.3g} rad")
    try:
        start, hints, start_notes = baseline_start(record, data)
    except IdentificationError as error:
        raise AnalysisError.naming(record.source, error) from error
    notes.extend(start_notes)
    n_train = round(policy.train_fraction * data.t.size)
    neutral = RecordScale.of(data.rig, data.t, data.y, start, 0.0)
    say("fitting the baseline model")
    head = data.head(n_train / data.t.size)
    baseline_train = fit(head, BASELINE, start, neutral)
    baseline = fit(data, BASELINE, baseline_train.values, neutral)
    baseline_prediction, base_sim = predict(data, BASELINE, baseline_train.values)
    baseline_heldout = heldout_rms(baseline_prediction, data.y, data.valid, n_train)
    timings["baseline"] = time.perf_counter() - clock
    _, full_sim = predict(data, BASELINE, baseline.values)
    deltas = full_sim.contacts.delta_max_m
    scale = RecordScale.of(data.rig, data.t, data.y, baseline.values,
                           float(np.median(deltas)) if deltas.size else 0.0)
    localization = localize(data, baseline, *motion_of(data, full_sim))
    say(f"baseline rms {baseline.rms:.3g} rad; {localization.text}")
    names = [c.name for c in candidates_for(data.experiment)]
    if causes is not None:
        names = [n for n in names if n in causes]
    fits = DecayFits(data, n_train, scale, hints, start, policy)
    # one pool of processes for the candidates and the forward selection's steps (none
    # with one worker): its processes start once per record
    with ProcessPoolExecutor(max_workers=workers) if workers > 1 else nullcontext() as pool:
        outcomes = _assessed(fits, [
            _Assessment(ModelSpec.of(n), baseline_train, baseline, baseline_prediction)
            for n in names], pool)
        for outcome in outcomes:
            say(f"  {outcome.model}: {outcome.verdict.why}")
        rivals = [o.rival for o in outcomes if o.rival is not None]
        if rivals:
            better = min(rivals, key=lambda r: r.rms)
            say(f"a candidate's solution led the baseline to a better fit (training rms "
                f"{better.rms:.3g} rad against {baseline_train.rms:.3g}): judging again")
            notes.append("the baseline was refitted from a candidate's solution (better basin)")
            baseline_train = better
            baseline = fit(data, BASELINE, baseline_train.values, neutral)
            baseline_prediction, base_sim = predict(data, BASELINE, baseline_train.values)
            baseline_heldout = heldout_rms(baseline_prediction, data.y, data.valid, n_train)
            outcomes = [rejudge(o, baseline, baseline_prediction, fits) for o in outcomes]
            _, full_sim = predict(data, BASELINE, baseline.values)
            localization = localize(data, baseline, *motion_of(data, full_sim))
        verdict = choose([o.verdict for o in outcomes])
        chosen, final, steps, indistinct = NONE, None, [], []
        if verdict is not None:
            first = next(o for o in outcomes if o.model == verdict.model)
            current, steps = forward_selection(
                DecaySteps(fits, baseline_train, outcomes, pool), first, verdict, policy, say)
            chosen = steps[0][0]
            final = current if len(current.model.causes) > 1 else None
            indistinct = forward_indistinct(
                verdict.model.causes[0], current.model.causes, baseline.residual,
                {o.model.causes[0]: o.full.residual for o in outcomes},
                {o.model.causes[0]: o.verdict.information_criterion_delta for o in outcomes},
                policy)
    timings["candidates"] = time.perf_counter() - clock - timings["baseline"]
    analysis = Analysis(
        record=record, data=data, n_train=n_train, baseline_train=baseline_train,
        baseline=baseline, baseline_prediction=baseline_prediction, candidates=outcomes,
        excluded=excluded_for(data.experiment), chosen=chosen, localization=localization,
        timings=timings, notes=notes, steps=steps, final=final, indistinct=indistinct,
        policy=policy,
    )
    say("the final model refitted on the large swings and on the rest")
    best = analysis.final_outcome
    found = [constancy_finding(data, best.full if best is not None else baseline, scale)]
    if chosen == NONE:
        found.append(implausible_gain_finding(outcomes))
    analysis.beside = [f for f in found if f is not None]
    if data.barrier:
        say("constant coefficient of restitution against Hunt-Crossley")
        analysis.restitution = compare_restitution(data, n_train, baseline, baseline_heldout,
                                                   base_sim)
    analysis.read()
    if analysis.unexplained:
        best = analysis.final_outcome
        final = best.full if best else baseline
        analysis.proposed_terms = proposed_terms(record, final.model, final.values)
        say("proposed terms (not named causes): " + (
            ", ".join(f"{t.term} in {t.region}" for t in analysis.proposed_terms) or "none"))
    timings["total"] = time.perf_counter() - clock
    say(f"cause: {chosen} ({timings['total']:.1f} s)")
    return analysis


def compare_restitution(
    data: FitData, n_train: int, baseline: FitResult, baseline_heldout: float, sim
) -> dict[str, Any]:
    """The paper's case: instantaneous impacts with constant e against Hunt-Crossley contact."""
    v = baseline.values
    speeds = np.abs(sim.contacts.theta_dot_in)
    speed = float(np.median(speeds)) if speeds.size else abs(v[q.omega_rad_s] * v[q.theta0_rad])
    e0 = restitution_from_hunt_crossley(v[q.mu0_s_per_m], data.rig.l_m, speed)
    if sim.contacts.count >= 2:
        ratios = np.abs(sim.contacts.theta_dot_out / sim.contacts.theta_dot_in)
        e0 = float(np.clip(np.median(ratios), 0.05, 0.99))
    start = {**v, q.e: e0}
    result = fit_restitution(data.t, data.y, data.valid, start, n_train)
    residual = result["residual"]
    rss = result["rss"]
    r = residual[np.isfinite(residual)]
    rms = float(math.sqrt(np.mean(r * r)))
    # Same judges as the candidates: positive values favour Hunt-Crossley.
    # a stand-in for the criterion, which reads only its residual and parameter count
    fake = FitResult(BASELINE, result["values"], {}, residual, result["n_params"], True, "")
    ic = information_criterion_delta(fake, baseline, data.noise_rad)
    return {
        "model": "instantaneous impacts at theta = 0 with constant coefficient of restitution e",
        "parameters": result["parameters"],
        "rms_residual": rms,
        "rss": rss,
        "heldout_rms": result["heldout_rms"],
        "hunt_crossley_rms_residual": baseline.rms,
        "hunt_crossley_heldout_rms": baseline_heldout,
        "rms_reduction_by_hunt_crossley": 1.0 - baseline.rms / rms if rms > 0 else 0.0,
        "information_criterion_delta_for_hunt_crossley": ic,
        "residual": residual,
        "curve": result["curve"],
        "values": result["values"],
    }
