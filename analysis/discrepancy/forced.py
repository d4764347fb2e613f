"""The discrepancy analysis of a forced record, on its own.

1. The regime is judged from the record (stroboscopic points locked to the tach, aware of
   the noise: :mod:`analysis.dynamics.measured_regime`), and the drive is measured.
2. The record is identified (:mod:`analysis.identify.forced`): equation error in flight
   for a cold start, then multiple shooting over short segments.
3. Every model (the baseline of docs/MODEL.md section 2, and the baseline extended by each
   named cause that can show) is fitted over the same short segments from that same cold
   start, the cause's own parameters from the record's hints (identified barrier and sensor
   zero, the table channel's amplitude and harmonic, the phase a lag would shift): a
   screening in which no model inherits another's compromises.
4. The baseline and the candidates that gained over it are fitted over the whole record in
   linked segments (:mod:`analysis.discrepancy.forced_models`), except a drive cause whose
   screened size the table channel found no different from none (it could only end
   disqualified).
5. The judges (:mod:`analysis.discrepancy.forced_judges`), best information criterion
   first: the criterion itself, and forecasts of the stretch after each fitted one from
   the state fitted there (a paired test over the stretches); on a chaotic record the
   invariant statistics of the model's own long run may veto.  The first cause both
   accept is the finding; the report is the one every experiment gives.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.discrepancy.candidates import candidates_for, excluded_for
from analysis.discrepancy.forced_judges import (
    disqualification,
    model_invariants_distance,
    table_contradiction,
    verdict_of,
)
from analysis.discrepancy.forced_models import (
    Layouts,
    ModelFits,
    SideBySide,
    as_fit_result,
    cause_hints,
    extend,
    fit_cause,
    fit_data_view,
    layouts,
    refit,
    screen_cause,
)
from analysis.discrepancy.forward import forward_selection
from analysis.discrepancy.forward import indistinct as forward_indistinct
from analysis.discrepancy.invariants import Invariants, invariants
from analysis.discrepancy.localize import localize
from analysis.discrepancy.outcome import Analysis, AnalysisError, CandidateOutcome
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.residual_reading import (
    Finding,
    ResidualReading,
    drive_frequency_finding,
    read_residual,
    timing_finding,
)
from analysis.discrepancy.selection import (
    Verdict,
    choose,
    information_criterion_delta,
)
from analysis.discrepancy.term_proposal import ProposedTerm, propose_terms
from analysis.dynamics.lines import FALSE_ALARM
from analysis.dynamics.regime import Regime
from analysis.experiments import FORCED
from analysis.extensions import BASELINE, NONE, ModelSpec
from analysis.identify.forced import (
    ForcedData,
    ForcedIdentification,
    ForcedModel,
    forced_data,
    identify_forced,
    record_regime,
)
from analysis.identify.result import Estimate, IdentificationError
from analysis.identify.shooting import Segments, ShootingFit
from analysis.progress import ProgressText
from analysis.records import Record


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
    # the forward selection: each cause added, with the verdict of its step against the
    # model before it (the first step's against the baseline), and the final model
    layouts: Layouts
    steps: list[tuple[str, Verdict]] = field(default_factory=list)
    final: ModelFits | None = None
    indistinct: list[dict[str, Any]] = field(default_factory=list)


def analyze_forced_fits(
    record_or_data, *, priors: Mapping[str, float] | None = None,
    causes: Sequence[str] | None = None, chaotic: bool = False, period: int = 1,
    progress: ProgressText | None = None, threads: int | None = None,
    policy: SelectionPolicy = DEFAULT_POLICY,
) -> ForcedOutcome:
    """Identify, fit the baseline and every candidate, judge them by ``policy``'s rules.

    Every candidate is fitted for SCREEN_ITERATIONS; the policy's ``refined`` best (by the
    information criterion) are fitted to convergence, except those that screened its
    ``rival_screened`` share or less of a refined cause that already leaves white noise; the ones
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
    say(f"screening every cause over {ident.short.count} short segments, and fitting the "
        "baseline model over the record")

    with SideBySide(threads) as batch:
        # the baseline screened, then fitted over the record: the longest, so it starts first
        baseline = batch.add(_screened_and_fitted, data, BASELINE, ident, hints, lay)
        started = {n: batch.add(screen_cause, data, ModelSpec.of(n), ident, hints)
                   for n in names}
    screened_none, base_full = baseline.result
    screened = {NONE: screened_none, **{n: fit.result for n, fit in started.items()}}
    base_short = ModelFits(BASELINE, screened[NONE])
    screened |= rescreened_from_baseline(data, ident, screened, threads, policy)
    bic = {n: _bic(data, base_short, screened[n]) for n in names}
    say("screened: " + ", ".join(f"{n} {bic[n]:.3g}" for n in sorted(bic, key=lambda n: -bic[n])))
    timings["screening"] = time.perf_counter() - clock - timings["identification"]
    base = ModelFits(BASELINE, base_full)
    say(f"baseline rms {base_full.rms:.3g} rad ({base_full.rms / data.noise_rad:.3g} x noise)")
    fits = _fit_over_record(data, names, screened, bic, base_full, lay, threads, period, say,
                            policy)
    # The judges, best information criterion first: forecasts over the training stretches
    # (and, on a chaotic record, the invariant statistics of the model's own long run); the
    # first cause they accept is the finding, and the rest need no training fits.
    # (a cause whose values no real rig can have explains nothing: it needs no forecasts)
    passing = sorted((n for n in names if bic[n] > policy.bic_margin
                      and not (n in fits and disqualification(data, ModelSpec.of(n), fits[n],
                                                              policy))),
                     key=lambda n: -bic[n])
    measured = base_distance = None
    if passing:
        base = ModelFits(BASELINE, base_full, refit(data, BASELINE, base_full, lay, threads,
                                                    heldout_s=data.segment_s))
        if chaotic:
            measured = invariants(data.t, data.y, data.drive.frequency_hz,
                                  data.drive.phase0_rad)
            base_distance = model_invariants_distance(data, measured, BASELINE, base_full)
    judged, trains, accepted = _judge_in_order(
        data, passing, fits, base, lay, threads, measured, base_distance, policy)
    steps: list[tuple[str, Verdict]] = []
    final = indistinct = None
    if accepted is not None:
        final, steps = forward_selection(
            ForcedSteps(data, ident, hints, screened, fits, lay, threads, measured, period,
                        policy, accepted),
            ModelFits(ModelSpec.of(accepted), fits[accepted], trains[accepted]),
            judged[accepted], policy, say)
        indistinct = forward_indistinct(
            accepted, final.model.causes, base.full.residual,
            {name: fit.residual for name, fit in fits.items()}, bic, policy)
    outcomes = []
    for name in names:
        model_fits = ModelFits(ModelSpec.of(name), fits.get(name, screened[name]),
                               trains.get(name))
        verdict = judged.get(name) or verdict_of(
            data, model_fits, base if name in fits else base_short, lay, policy=policy)
        say(f"  {name}: {verdict.why}")
        outcomes.append((model_fits, verdict))
    timings["fits"] = time.perf_counter() - clock - sum(timings.values())
    return ForcedOutcome(data, ident, base, outcomes, chaotic, timings, notes, lay, steps,
                         final, indistinct or [])


def rescreened_from_baseline(
    data: ForcedData, ident: ForcedIdentification, screened: Mapping[str, ShootingFit],
    threads: int | None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> dict[str, ShootingFit]:
    """The screenings that ended worse than the baseline's, fitted again from the baseline's
    own solution with the cause neutral (the forward selection's step), where that ends
    closer.  A model that holds the baseline cannot explain less: its cold start found a
    worse basin, which says nothing against the cause
    (``tests/discrepancy/test_screening.py``, the screening stuck worse than the baseline).
    """
    base = screened[NONE]
    with SideBySide(threads) as batch:
        nested = {name: batch.add(extend, data, BASELINE, base, name, ident.short,
                                  max_iterations=policy.step_screen_iterations)
                  for name, fit in screened.items() if name != NONE and fit.rss > base.rss}
    return {name: fit.result for name, fit in nested.items()
            if fit.result.rss < screened[name].rss}


def _fit_over_record(
    data: ForcedData, names: list[str], screened: Mapping[str, ShootingFit],
    bic: dict[str, float], base_full: ShootingFit, lay: Layouts, threads: int | None,
    period: int, say: ProgressText, policy: SelectionPolicy,
) -> dict[str, ShootingFit]:
    """Fit the policy's ``refined`` best screened causes over the whole record (see
    analyze_forced_fits); ``bic`` is updated in place: a fitted cause's gain over the
    record, and an unfitted one's screening gain capped at the policy's ``bic_margin`` (it
    did not come close)."""
    ranked = sorted(names, key=lambda n: -bic[n])
    screened_gain = dict(bic)
    fits: dict[str, ShootingFit] = {}
    complete = None  # the first refined cause that gains, is plausible and leaves white noise
    for name in [n for n in ranked if bic[n] > 0.0][:policy.refined]:
        if contradiction := table_contradiction(data, ModelSpec.of(name), screened[name],
                                                absent_only=True, policy=policy):
            say(f"  {name} not fitted over the record: its screening gives {contradiction}")
            continue
        if complete is not None and \
                screened_gain[name] < policy.rival_screened * screened_gain[complete]:
            say(f"  {name} not fitted over the record: {complete} leaves white noise and "
                f"{name} screened {screened_gain[complete] / screened_gain[name]:.3g} x lower")
            continue
        fits[name] = _fit_cause_over_record(data, name, screened[name], base_full, fits, lay,
                                            threads, policy)
        bic[name] = _bic(data, ModelFits(BASELINE, base_full), fits[name])
        say(f"  {name} over the record: BIC gain {bic[name]:.3g}")
        if complete is None and bic[name] > policy.bic_margin and not disqualification(
                data, ModelSpec.of(name), fits[name], policy) \
                and not _structured(data, fits[name], period):
            complete = name
    _finish_rivals(data, fits, bic, base_full, lay, threads, say, policy)
    for name in names:
        if name not in fits:  # judged on its screening: it did not come close
            bic[name] = min(bic[name], policy.bic_margin)
    return fits


def _finish_rivals(
    data: ForcedData, fits: dict[str, ShootingFit], bic: dict[str, float],
    base_full: ShootingFit, lay: Layouts, threads: int | None, say: ProgressText,
    policy: SelectionPolicy,
) -> None:
    """Fits stopped at their iteration cap while within the policy's ``rival_bic`` share of
    the best cause's gain go on until they converge (at most ``rival_rounds`` more caps):
    the judges compare finished fits.
    A wrong cause's crawl changes nothing, but the right one can crawl too: a contact
    exponent, whose stiffness must follow it over decades, stood at 0.72 of a barrier
    offset's gain after 12 iterations and at 1.04 of it after 40."""
    for _ in range(policy.rival_rounds):
        best = max((bic[n] for n in fits), default=0.0)
        unfinished = [n for n, fit in fits.items() if not fit.success
                      and bic[n] > policy.bic_margin and bic[n] >= policy.rival_bic * best]
        if not unfinished:
            return
        for name in unfinished:
            fits[name] = refit(data, ModelSpec.of(name), fits[name], lay, threads)
            bic[name] = _bic(data, ModelFits(BASELINE, base_full), fits[name])
            say(f"  {name} fitted on (it had not converged): BIC gain {bic[name]:.3g}")


def _fit_cause_over_record(
    data: ForcedData, name: str, screened: ShootingFit, base_full: ShootingFit,
    fits: Mapping[str, ShootingFit], lay: Layouts, threads: int | None,
    policy: SelectionPolicy,
) -> ShootingFit:
    """One cause's fit over the record, restarted when it ends in a worse basin than the
    baseline's."""
    # the best full fit so far lends its states when it fits the record closely
    best = min([base_full, *fits.values()], key=lambda f: f.rms)
    seed = best if best.rms < policy.seed_rms * data.noise_rad else None
    model = ModelSpec.of(name)
    fit = fit_cause(data, model, screened, lay, threads, seed)
    # a model ending worse than the baseline found a worse basin: start again from the
    # baseline's optimum, then (when the first start was another model's states) from
    # its own states drawn onto the data afresh
    if fit.rss > base_full.rss:
        fit = min(fit, extend(data, BASELINE, base_full, name, lay.full, threads),
                  key=lambda f: f.rss)
    if fit.rss > base_full.rss and seed is not None:
        fit = min(fit, fit_cause(data, model, screened, lay, threads), key=lambda f: f.rss)
    return fit


def _judge_in_order(
    data: ForcedData, passing: list[str], fits: Mapping[str, ShootingFit], base: ModelFits,
    lay: Layouts, threads: int | None, measured: Invariants | None,
    base_distance: float | None, policy: SelectionPolicy,
) -> tuple[dict[str, Verdict], dict[str, ShootingFit], str | None]:
    """Judge the passing causes, best first, by forecasts (and, with ``measured``, the
    invariants) until one earns its keep: the verdicts, the training fits made, and the
    accepted cause (None when none is); the rest are not judged further."""
    judged: dict[str, Verdict] = {}
    trains: dict[str, ShootingFit] = {}
    accepted = None
    for name in passing:
        if accepted is not None:
            judged[name] = verdict_of(
                data, ModelFits(ModelSpec.of(name), fits[name]), base, lay,
                not_judged=f"not judged further: {accepted} scores higher and earns its place",
                policy=policy)
            continue
        model = ModelSpec.of(name)
        distances: tuple[float | None, float | None] = (None, None)
        if measured is not None:
            distances = (base_distance,
                         model_invariants_distance(data, measured, model, fits[name]))
        trains[name] = refit(data, model, fits[name], lay, threads, heldout_s=data.segment_s)
        judged[name] = verdict_of(data, ModelFits(model, fits[name], trains[name]), base, lay,
                                  distances, policy=policy)
        if judged[name].earns_keep:
            accepted = name
    return judged, trains, accepted


class ForcedSteps:
    """The forward selection's steps on a forced record (:mod:`analysis.discrepancy.forward`).

    A step screens every cause not yet in on the short segments, each added to the current
    model's screening solution and fitted a few iterations, against the current model
    continued to its optimum (:func:`screened_beside`; a cause the first one masked gains
    here, where it could not against the baseline); when none gains there, over the whole
    record from the current model's fit (:func:`screened_over_record`); a drive cause whose
    screened size the table channel found absent is not fitted on.  The best are fitted over
    the record from three starts, the closest kept: the current model's optimum with the
    cause neutral, afresh as every single cause is (``_fit_afresh``), and the step's
    screening solution (the cause's size found on the short segments beside the current
    model), against the current model continued as long.  A cause that must move the rig's
    own parameters far to show stays near its neutral start (a sensor lag whose attenuation
    the viscous damping had taken, held at 0), and afresh it misses what the current model's
    causes explain; its screening found both.  The judges are the information criterion, the
    forecasts, and on a chaotic record the invariants' veto.
    A step is tried while the current model's residual is not white noise, not even
    correlated beyond chance (a Ljung-Box p of FALSE_ALARM): structure too small to call the
    model unexplained can still be a second cause's (quadratic drag beside a barrier offset
    on a chaotic record left 0.11 x the noise's rms, with p = 2e-25).  The step's own
    excess-ratio rule keeps out a 0.46 mrad sensor zero beside a lag and a harmonic (none
    in the truth) that forecast 0.3 % better, 3 standard errors clear, over a minute."""

    def __init__(
        self, data: ForcedData, ident: ForcedIdentification, hints: Mapping[str, float],
        screened: Mapping[str, ShootingFit], fits: Mapping[str, ShootingFit], lay: Layouts,
        threads: int | None, measured: Invariants | None, period: int,
        policy: SelectionPolicy, first: str,
    ) -> None:
        self.data, self.ident, self.hints, self.lay = data, ident, hints, lay
        self.screened, self.fits, self.threads = screened, fits, threads
        self.measured, self.period, self.policy = measured, period, policy
        self.names = [n for n in screened if n != NONE]
        self.short = screened[first]  # the current model's screening solution
        self.distance: float | None = None  # its invariants' distance (chaotic records)
        self.beside: dict[str, tuple[float, ShootingFit]] = {}  # the last step's screening
        self.next_distance: float | None = None

    def open_structure(self, current: ModelFits) -> str | None:
        left = _residual_reading(self.data, current.full, self.period)
        if left.structured or left.ljung_box_p < FALSE_ALARM:
            return None
        return (f"{left.why}, and its correlation is no more than white noise's (Ljung-Box "
                f"p {left.ljung_box_p:.2g})")

    def screen(self, current: ModelFits) -> dict[str, float]:
        self.beside = screened_beside(self.data, self.ident, current.model, self.short,
                                      self.names, self.threads, self.policy)
        gains = {name: gain for name, (gain, _) in self.beside.items()}
        if max(gains.values(), default=-np.inf) > self.policy.bic_margin:
            return gains
        return screened_over_record(self.data, current, self.lay, self.names, self.threads,
                                    self.policy)

    def refused(self, current: ModelFits, name: str) -> str | None:
        return table_contradiction(self.data, current.model.plus(name), self.beside[name][1],
                                   absent_only=True, policy=self.policy)

    def fit(self, current: ModelFits, names: Sequence[str]
            ) -> tuple[ShootingFit, dict[str, ShootingFit]]:
        data, lay, model = self.data, self.lay, current.model
        with SideBySide(self.threads) as batch:
            parent = batch.add(refit, data, model, current.full, lay)
            starts = {name: [
                batch.add(extend, data, model, current.full, name, lay.full),
                batch.add(_fit_afresh, data, model.plus(name), self.ident, self.hints, lay),
                batch.add(fit_cause, data, model.plus(name), self.beside[name][1], lay,
                          seed=current.full),
            ] for name in names}
        return parent.result, {
            name: min((start.result for start in starts[name]), key=lambda f: f.rss)
            for name in names}

    def gain(self, parent: ShootingFit, fit: ShootingFit) -> float:
        return _bic(self.data, ModelFits(BASELINE, parent), fit)

    def disqualification(self, model: ModelSpec, fit: ShootingFit) -> str | None:
        return disqualification(self.data, model, fit, self.policy)

    def estimates(self, fit: ShootingFit) -> Mapping[str, Estimate]:
        return fit.estimates

    def full(self, fitted: ModelFits) -> ShootingFit:
        return fitted.full

    def judge(self, current: ModelFits, parent: ShootingFit, model: ModelSpec,
              fit: ShootingFit) -> tuple[ModelFits, Verdict]:
        data = self.data
        train = refit(data, model, fit, self.lay, self.threads, heldout_s=data.segment_s)
        distances: tuple[float | None, float | None] = (None, None)
        if self.measured is not None:
            if self.distance is None:
                self.distance = model_invariants_distance(data, self.measured, current.model,
                                                          current.full)
            distances = (self.distance,
                         model_invariants_distance(data, self.measured, model, fit))
        self.next_distance = distances[1]
        candidate = ModelFits(model, fit, train)
        return candidate, verdict_of(data, candidate,
                                     ModelFits(current.model, parent, current.train), self.lay,
                                     distances, policy=self.policy)

    def adopted(self, fitted: ModelFits, name: str | None) -> None:
        if name is not None:
            self.short, self.distance = self.beside[name][1], self.next_distance
        else:  # an earlier cause dropped: the one left is a single cause fitted already
            self.short = self.screened[fitted.model.causes[0]]

    def alone(self, model: ModelSpec) -> ModelFits | None:
        if len(model.causes) == 1 and model.causes[0] in self.fits:
            return ModelFits(model, self.fits[model.causes[0]])
        return None


def screened_beside(
    data: ForcedData, ident: ForcedIdentification, current: ModelSpec, short: ShootingFit,
    names: Sequence[str], threads: int | None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> dict[str, tuple[float, ShootingFit]]:
    """A step's screening: each of ``names`` not in model ``current`` added to its short
    fit ``short`` and fitted the policy's ``step_screen_iterations``, with its
    information-criterion gain over ``current`` continued to its optimum (up to
    ``step_parent_iterations``).  A screening
    stops at its cap, and a cause added to a fit still moving gains what the fit would have
    gained by iterating on: a drive harmonic beside a sensor cubic on a chaotic record
    gained 1630 over the cubic continued as long, and over the record it did not differ
    from none.  The yardstick is the same for every cause, so it moves no cause ahead of
    another (starting the causes from the continued fit did: a barrier offset fell out of
    the two tried beside a sensor cubic, and a lag and a zero were named in its place)."""
    return _screened(data, current, short, ident.short, names, threads,
                     policy.step_screen_iterations, policy.step_parent_iterations)


def screened_over_record(
    data: ForcedData, current: ModelFits, lay: Layouts, names: Sequence[str],
    threads: int | None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> dict[str, float]:
    """A step's screening over the whole record, for when none of ``names`` gained over the
    policy's ``bic_margin`` on the short segments: each cause not in ``current`` added to its
    fit over the record with the cause neutral and fitted ``step_screen_iterations``, its
    gain over ``current`` continued as long.  An effect that builds up over a swing shows
    on the 0.1 s segments hardly at all: quadratic drag beside a drive harmonic (a 10 Hz
    chaotic record) screened -0.335 there, and over the record gained 2.6e3 and was judged
    right."""
    iterations = policy.step_screen_iterations
    screened = _screened(data, current.model, current.full, lay.full, names, threads,
                         iterations, iterations)
    return {name: gain for name, (gain, _) in screened.items()}


def _screened(
    data: ForcedData, current: ModelSpec, fit: ShootingFit, segments: Segments,
    names: Sequence[str], threads: int | None, iterations: int, parent_iterations: int,
) -> dict[str, tuple[float, ShootingFit]]:
    """Each of ``names`` not in model ``current`` added to its fit ``fit`` over
    ``segments`` and fitted ``iterations``: its information-criterion gain over ``current``
    continued ``parent_iterations``, and its fit."""
    with SideBySide(threads) as batch:
        continued = batch.add(extend, data, current, fit, None, segments,
                              max_iterations=parent_iterations)
        added = {name: batch.add(extend, data, current, fit, name, segments,
                                 max_iterations=iterations)
                 for name in names if name not in current.causes}
    yardstick = ModelFits(current, continued.result)
    return {name: (_bic(data, yardstick, f.result), f.result) for name, f in added.items()}


def _screened_and_fitted(
    data: ForcedData, model: ModelSpec, ident: ForcedIdentification,
    hints: Mapping[str, float], lay: Layouts, threads: int | None,
) -> tuple[ShootingFit, ShootingFit]:
    """Model ``model`` screened, then fitted over the record from its screening."""
    short = screen_cause(data, model, ident, hints, threads)
    return short, fit_cause(data, model, short, lay, threads)


def _fit_afresh(
    data: ForcedData, model: ModelSpec, ident: ForcedIdentification,
    hints: Mapping[str, float],
    lay: Layouts, threads: int | None,
) -> ShootingFit:
    """Model ``model`` fitted over the record the way every single cause is: screened from
    the identification's start, then fitted from its screening.  The nested start (the
    current model's optimum, the new cause neutral) inherits the compromises the current
    model made for the cause it lacked: a sensor cubic alone fitted a barrier 0.025 rad
    away by a rigid contact (K on its bound), and from there the barrier did not move."""
    return _screened_and_fitted(data, model, ident, hints, lay, threads)[1]


def _residual_reading(data: ForcedData, fit: ShootingFit, period: int) -> ResidualReading:
    """The residual of a fit over the record, judged against the record's white noise."""
    return read_residual(data.t, fit.residual, data.valid, data.noise_rad,
                         drive_frequency_hz=data.drive.frequency_hz, subharmonic=period)


def _structured(data: ForcedData, fit: ShootingFit, period: int) -> bool:
    """Whether a fit over the record leaves more than white noise."""
    return _residual_reading(data, fit, period).structured


def _bic(data: ForcedData, base: ModelFits, fit: ShootingFit) -> float:
    # the criterion reads only the fits' residuals and parameter counts, not their models
    return information_criterion_delta(as_fit_result(base.full, base.model),
                                       as_fit_result(fit, base.model), data.noise_rad)


def regime_summary(regime: Regime) -> dict[str, Any]:
    """The regime for the report: kind, period, label and the evidence a reader checks."""
    keep = ("transient_periods", "transient_s", "periods_in_record", "tolerance_rad", "K",
            "lyapunov_per_period", "subharmonics", "superharmonics", "incommensurate")
    return {"kind": regime.kind, "period": regime.period, "label": regime.label,
            "evidence": {k: regime.evidence[k] for k in keep if k in regime.evidence}}


def analyze_forced(
    record: Record, *, priors: Mapping[str, float] | None = None,
    causes: Sequence[str] | None = None, progress: ProgressText | None = None,
    threads: int | None = None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> Analysis:
    """The discrepancy analysis of a forced record (see the module's docstring), decided
    by ``policy``'s rules."""
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    try:
        data = forced_data(record)
    except IdentificationError as error:
        raise AnalysisError.naming(record.source, error) from error
    regime = record_regime(record, data)
    chaotic = regime.kind == "chaotic"
    data = data.for_regime(regime.kind)
    say(f"forced: {data.n_valid} samples at {1 / data.dt:.4g} Hz, noise {data.noise_rad:.3g} "
        f"rad, drive {data.drive.frequency_hz:.6g} Hz ({data.drive.frequency_source}); "
        f"regime {regime.label}")
    judge_time = time.perf_counter() - clock
    try:
        out = analyze_forced_fits(data, priors=priors, causes=causes, chaotic=chaotic,
                                  period=regime.period or 1,
                                  progress=say, threads=threads, policy=policy)
    except IdentificationError as error:
        raise AnalysisError.naming(record.source, error) from error
    verdict = choose([v for _, v in out.candidates])
    chosen = out.steps[0][0] if out.steps else \
        verdict.model.causes[0] if verdict is not None else NONE
    base = out.base
    view = fit_data_view(data)
    baseline = as_fit_result(base.full, BASELINE)
    candidates = [
        CandidateOutcome(
            model=fits.model,
            train=as_fit_result(fits.train if fits.train is not None else fits.full, fits.model),
            full=as_fit_result(fits.full, fits.model),
            verdict=v,
            prediction=(fits.train if fits.train is not None else fits.full).prediction,
        )
        for fits, v in out.candidates
    ]
    final = None
    if out.final is not None and len(out.final.model.causes) > 1:
        f = out.final
        final = CandidateOutcome(
            model=f.model, train=as_fit_result(f.train if f.train is not None else f.full,
                                               f.model),
            full=as_fit_result(f.full, f.model),
            verdict=verdict_of(data, f, base, out.layouts, policy=policy),
            prediction=(f.train if f.train is not None else f.full).prediction)
    in_contact = base.full.true_angle > 0.0
    localization = localize(view, baseline, base.full.rate, _widened(in_contact))
    shown = out.final if final is not None else \
        next((f for f, _ in out.candidates if f.model.causes == (chosen,)), None)
    if shown is None and out.candidates:
        shown = max(out.candidates, key=lambda fv: fv[1].information_criterion_delta)[0]
    notes = [*out.notes]
    if chaotic:
        notes.append(f"chaotic response: fitted in segments of {data.segment_s:g} s, and a "
                     "cause must also bring the invariant statistics of the model's own long "
                     "run (Poincare section, turning points, spectral lines) closer to the "
                     "record's")
    timings = {"regime": judge_time, **out.timings, "total": time.perf_counter() - clock}
    adopted = ", ".join(name for name, _ in out.steps) or chosen
    say(f"cause{'s' if len(out.steps) > 1 else ''}: {adopted} ({timings['total']:.1f} s)")
    analysis = Analysis(
        record=record, data=view, n_train=view.t.size,
        baseline_train=as_fit_result(base.train if base.train is not None else base.full,
                                     BASELINE),
        baseline=baseline, baseline_prediction=base.full.prediction, candidates=candidates,
        excluded=excluded_for(FORCED.name), chosen=chosen, localization=localization,
        zero_one_k=regime.evidence.get("K"), chaotic=chaotic, timings=timings, notes=notes,
        regime=regime_summary(regime), drive=data.drive.as_json(),
        baseline_heldout_rms=base.train.forecast_rms if base.train is not None else None,
        curves=(base.full.prediction, shown.full.prediction if shown is not None else None),
        steps=out.steps, final=final, indistinct=out.indistinct, policy=policy,
        heldout_description=(
            f"forecasts over the {data.segment_s:g} s after each fitted stretch of "
            f"{data.segment_s:g} s, "
            "from the state fitted at that stretch's start"
        ),
        drive_findings=_drive_findings(record, data),
    ).read()
    if analysis.unexplained:
        clock = time.perf_counter()
        analysis.proposed_terms = proposed_terms(data, out.final or base)
        timings["term_proposal"] = time.perf_counter() - clock
        say("proposed terms (not named causes): " + (
            ", ".join(f"{t.term} in {t.region}" for t in analysis.proposed_terms) or "none"))
    return analysis


def proposed_terms(data: ForcedData, fits: ModelFits) -> list[ProposedTerm]:
    """The terms the residual acceleration of a model fitted over the record asks for
    (:mod:`analysis.discrepancy.term_proposal`), at the data's true angle: the measured one
    with the model's sensor (its measured minus its true angle there) taken off."""
    fit = fits.full
    packed = ForcedModel(data, fits.model.causes).packed(fit.values)
    theta = data.y - (fit.prediction - fit.true_angle)
    return propose_terms(data.t, theta, data.valid, packed, fit.true_angle, fit.rate)


def _drive_findings(record: Record, data: ForcedData) -> list[Finding]:
    """What the drive channels say against the stated drive: the tach's frequency, and the
    table channel's phase at the tach pulses."""
    clock = data.drive.clock
    if clock is None or clock.source != "tach":
        return []
    found = [drive_frequency_finding(clock, data.drive.stated_frequency_hz)]
    if record.table_m is not None:
        found.append(timing_finding(np.arange(record.table_m.size) / record.sample_rate_hz,
                                    record.table_m, clock))
    return [f for f in found if f is not None]


def _widened(mask: np.ndarray, guard: int = 2) -> np.ndarray:
    """``mask`` grown by ``guard`` samples either side."""
    out = mask.copy()
    for shift in range(1, guard + 1):
        out[shift:] |= mask[:-shift]
        out[:-shift] |= mask[shift:]
    return out
