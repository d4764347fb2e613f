"""Causes that hold across a sweep: the forward selection of every record
(:func:`analysis.discrepancy.forward.forward_selection`, the one engine) run from the
baseline over every step at once, each cause's parameters shared by the steps.

The baseline (docs/MODEL.md section 2: the barrier at its nominal place, the sensor's zero
at 0) is fitted over every step from the rig's identification; a step of the selection
(:class:`SweepSteps`) screens every cause not yet in beside the current model over the
steps' linked segments (the cause's parameters starting where the identification put
them: its barrier, its sensor zero, its table amplitude; a screening that ends worse than
the current model is screened again from that model's own solution, and the closer kept),
fits the best further, and
judges the best by the information criterion and by forecasts of the stretch after each
fitted one, over every step (the training layout of a single forced record, step by
step).  The policy's rules decide, as for a single record.  The final model is fitted on
until it converges (:func:`fitted_on`), so that its causes' parameters and intervals are
read at its optimum.

A cause named so must hold one size for the whole sweep.  Each named cause's parameters
are then fitted once more with a size of each step's own (``name@N``, the other
parameters shared): when the steps' sizes differ beyond their intervals (chi-square on
their standard errors, the FALSE_ALARM quantile divided among the causes' parameters),
the cause explains the sweep only with a different size on each step, which is no
explanation; it is not named, and how its size would have to vary with the drive (a
trend in the setting, or none) is a ``constancy`` residual finding.

The table channel checks a drive cause across the sweep as it does on a single record
(:func:`analysis.discrepancy.forced_judges.table_gaps`): one shared size of the table's
amplitude error (``eps``) or second harmonic (``h2``) is measured by the laser on every
step that has a table channel, and those steps' measurements, combined by their inverse
variances (:func:`table_sizes`), are what a size fitted from the angle must not
contradict.  A screened cause whose size the laser found absent is not fitted further;
a fitted one the laser contradicts is disqualified.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import stats

from analysis import quantities as q
from analysis.discrepancy.candidates import candidates_for
from analysis.discrepancy.forced_judges import table_gaps
from analysis.discrepancy.forced_models import (
    REFINE_ITERATIONS,
    SideBySide,
    as_fit_result,
    level_hints,
    true_angle_states,
)
from analysis.discrepancy.forward import forward_selection
from analysis.discrepancy.policy import SelectionPolicy
from analysis.discrepancy.residual_reading import Finding, read_residual
from analysis.discrepancy.selection import Verdict, information_criterion_delta, paired_gain_z
from analysis.dynamics.lines import FALSE_ALARM
from analysis.experiments import FORCED
from analysis.extensions import BASELINE, ModelSpec, cause, implausibility
from analysis.identify.forced import record_segments
from analysis.identify.intervals import Z95
from analysis.identify.result import Estimate
from analysis.identify.shooting import FreeParameter, ShootingFit
from analysis.progress import ProgressText
from analysis.sweep.constancy import spread_across_steps
from analysis.sweep.fit import (
    STEP_MARK,
    JoinedSegments,
    SweepData,
    SweepIdentification,
    SweepModel,
    joined,
    joined_inherited_states,
    joined_smoothed_states,
    step_name,
    sweep_parameters,
    sweep_state_steps,
)


@dataclass(frozen=True)
class SweepModelFits:
    """A model fitted over every step, and (when judged on forecasts) to the training
    stretches."""

    model: ModelSpec
    full: ShootingFit
    train: ShootingFit | None = None


@dataclass(frozen=True)
class SweepLayouts:
    """Every step cut as a single forced record is: linked segments over everything, and
    alternating fitted and forecast stretches."""

    full: JoinedSegments
    train: JoinedSegments


def sweep_layouts(data: SweepData) -> SweepLayouts:
    """Each step's two layouts, joined."""
    return SweepLayouts(joined(data, [record_segments(d) for d in data.steps]),
                        joined(data, [record_segments(d, heldout_s=d.segment_s)
                                      for d in data.steps]))


def fit_on(
    data: SweepData, model: ModelSpec, start: Mapping[str, float],
    hints: Mapping[str, float], layout: JoinedSegments, origin: ShootingFit,
    origin_layout: JoinedSegments, threads: int | None, max_iterations: int,
    per_step: Sequence[str] = (),
) -> ShootingFit:
    """Model ``model`` fitted over ``layout`` from values ``start`` (a cause's parameters
    from ``hints`` where ``start`` lacks them) and the states of ``origin`` (a fit over
    ``origin_layout``), its measured angle read through this model's sensor.
    ``per_step``: parameters fitted with a value of each step's own (``name@N``)."""
    free = sweep_parameters(data, model, start, hints, phase_free=False)
    if per_step:
        free = _per_step(data, free, per_step)
    values = {p.name: p.start for p in free}
    dt = data.steps[0].dt
    fallback = joined_smoothed_states(data, layout, values.get(q.offset_rad, 0.0))
    rates = joined_inherited_states(layout, origin_layout, origin.states, fallback)
    measured = origin.prediction[layout.segments.start]
    measured = np.where(np.isfinite(measured), measured, fallback[:, 0])
    states = true_angle_states(np.column_stack([measured, rates[:, 1]]), model, values, dt)
    problem = SweepModel(data, model.causes).problem(layout, free, {}, threads=threads)
    return problem.fit(states, state_steps=sweep_state_steps(data),
                       max_iterations=max_iterations)


def _per_step(data: SweepData, free: list[FreeParameter], names: Sequence[str]
              ) -> list[FreeParameter]:
    """``free`` with each of ``names`` replaced by one parameter per step."""
    out = []
    for p in free:
        if p.name not in names:
            out.append(p)
            continue
        out += [replace(p, name=step_name(p.name, number), part=k)
                for k, number in enumerate(data.numbers)]
    return out


def table_sizes(data: SweepData) -> dict[str, Estimate]:
    """What the table channel measured of the drive causes' sizes over the sweep: each
    size's measurements on the steps with a table channel, combined by their inverse
    variances, with the 95 % interval of the combination (the plain mean, with no interval,
    when no step's measurement has one); empty when no step has a table channel."""
    by_name: dict[str, list[Estimate]] = {}
    for step in data.steps:
        for name, estimate in step.drive.measured_sizes().items():
            by_name.setdefault(name, []).append(estimate)
    out = {}
    for name, estimates in by_name.items():
        known = [e for e in estimates if math.isfinite(e.half_width) and e.half_width > 0.0]
        if not known:
            out[name] = Estimate(float(np.mean([e.value for e in estimates])))
            continue
        weights = np.array([(Z95 / e.half_width) ** 2 for e in known])
        mean = float(np.dot(weights, [e.value for e in known]) / weights.sum())
        half = Z95 / math.sqrt(float(weights.sum()))
        out[name] = Estimate(mean, (mean - half, mean + half))
    return out


def gain_over(data: SweepData, parent: ShootingFit, fit: ShootingFit) -> float:
    """The information-criterion gain of ``fit`` over ``parent`` (the criterion reads only
    the fits' residuals and parameter counts)."""
    return information_criterion_delta(as_fit_result(parent, BASELINE),
                                       as_fit_result(fit, BASELINE), data.noise_rad)


class SweepSteps:
    """The forward selection's steps on a sweep (see the module's docstring)."""

    def __init__(self, ident: SweepIdentification, lay: SweepLayouts,
                 hints: Mapping[str, float], names: Sequence[str], threads: int | None,
                 policy: SelectionPolicy) -> None:
        self.ident, self.data, self.lay, self.hints = ident, ident.data, lay, hints
        self.names, self.threads, self.policy = list(names), threads, policy
        self.table = table_sizes(self.data)
        self.beside: dict[str, ShootingFit] = {}
        self.singles: dict[str, SweepModelFits] = {}

    def _fit(self, model: ModelSpec, origin: ShootingFit, iterations: int, *,
             layout: JoinedSegments | None = None, origin_layout: JoinedSegments | None = None,
             start: Mapping[str, float] | None = None, threads: int | None = None
             ) -> ShootingFit:
        """``model`` fitted from ``origin``'s states (over ``origin_layout``, the full
        layout unless given) and values (or ``start``); the hints start a new cause's
        parameters, a model's own continue where they are."""
        start = origin.values if start is None else start
        hints = {k: v for k, v in level_hints(model, self.hints).items() if k not in start}
        return fit_on(self.data, model, start, hints, layout or self.lay.full, origin,
                      origin_layout or self.lay.full, threads, iterations)

    def _from_identification(self, current: SweepModelFits, name: str) -> dict[str, float]:
        """Where cause ``name`` beside ``current`` starts: the rig's parameters where the
        identification put them (its barrier and sensor zero free, its motion is the
        record's even where the current model's is not), the current causes' own where
        they are fitted, the new cause's from the hints."""
        ident = self.ident.fit.values
        rig = {k: ident[k] for k in (q.omega_rad_s, q.zeta, q.K_N_per_m1_5, q.mu0_s_per_m)}
        own = {k: v for k, v in current.full.values.items() if k not in rig}
        return {**own, **rig}

    def open_structure(self, current: SweepModelFits) -> str | None:
        data, readings = self.data, []
        for k, d in enumerate(data.steps):
            left = read_residual(d.t, current.full.residual[data.step_slice(k)], d.valid,
                                 d.noise_rad, drive_frequency_hz=d.drive.frequency_hz)
            if left.structured or left.ljung_box_p < FALSE_ALARM / len(data.steps):
                return None
            readings.append(left)
        return (f"on every step {readings[0].why}, and its correlation is no more than "
                "white noise's")

    def screen(self, current: SweepModelFits) -> dict[str, float]:
        model, origin = current.model, current.full
        policy = self.policy
        with SideBySide(self.threads) as batch:
            continued = batch.add(self._fit, model, origin, policy.step_parent_iterations)
            added = {name: batch.add(self._fit, model.plus(name), self.ident.fit,
                                     policy.step_screen_iterations,
                                     origin_layout=self.ident.segments,
                                     start=self._from_identification(current, name))
                     for name in self.names if name not in model.causes}
        parent = continued.result
        self.beside = {name: fit.result for name, fit in added.items()}
        # a screening that ends worse than the model it extends found a worse basin from
        # the identification's start (a model that holds the current one cannot explain
        # less): it is screened again from the current model's own solution, the cause at
        # its start, and the closer kept, as a single record's screenings are
        # (analysis.discrepancy.forced.rescreened_from_baseline); a chaotic sweep's lag
        # screened -112 from the identification, below the baseline it extends
        worse = [name for name, fit in self.beside.items() if fit.rms > parent.rms]
        with SideBySide(self.threads) as batch:
            again = {name: batch.add(self._fit, model.plus(name), parent,
                                     policy.step_screen_iterations) for name in worse}
        for name, fit in again.items():
            if fit.result.rms < self.beside[name].rms:
                self.beside[name] = fit.result
        return {name: gain_over(self.data, parent, fit) for name, fit in self.beside.items()}

    def refused(self, current: SweepModelFits, name: str) -> str | None:
        return table_gaps(self.table, current.model.plus(name), self.beside[name].estimates,
                          absent_only=True, policy=self.policy)

    def fit(self, current: SweepModelFits, names: Sequence[str]
            ) -> tuple[ShootingFit, dict[str, ShootingFit]]:
        with SideBySide(self.threads) as batch:
            parent = batch.add(self._fit, current.model, current.full, REFINE_ITERATIONS)
            fits = {name: batch.add(self._fit, current.model.plus(name), self.beside[name],
                                    REFINE_ITERATIONS) for name in names}
        return parent.result, {name: fit.result for name, fit in fits.items()}

    def gain(self, parent: ShootingFit, fit: ShootingFit) -> float:
        return gain_over(self.data, parent, fit)

    def disqualification(self, model: ModelSpec, fit: ShootingFit) -> str | None:
        return implausibility(model, fit.values) or \
            table_gaps(self.table, model, fit.estimates, policy=self.policy)

    def estimates(self, fit: ShootingFit) -> Mapping[str, Estimate]:
        return fit.estimates

    def full(self, fitted: SweepModelFits) -> ShootingFit:
        return fitted.full

    def judge(self, current: SweepModelFits, parent: ShootingFit, model: ModelSpec,
              fit: ShootingFit) -> tuple[SweepModelFits, Verdict]:
        with SideBySide(self.threads) as batch:
            base_train = batch.add(self._fit, current.model, parent, REFINE_ITERATIONS,
                                   layout=self.lay.train)
            train = batch.add(self._fit, model, fit, REFINE_ITERATIONS,
                              layout=self.lay.train)
        base_train, train = base_train.result, train.result
        stretches = self.lay.train.segments
        verdict = Verdict(
            model=model, information_criterion_delta=self.gain(parent, fit),
            heldout_rms_baseline=base_train.forecast_rms,
            heldout_rms_extended=train.forecast_rms, rms_baseline=parent.rms,
            rms_extended=fit.rms, noise_rad=self.data.noise_rad,
            n_heldout=int(np.count_nonzero(np.isfinite(base_train.forecast_residual))),
            forecast_z=paired_gain_z(base_train.forecast_residual, train.forecast_residual,
                                     zip(stretches.fit_stop, stretches.stop, strict=True)),
            implausible=self.disqualification(model, fit), policy=self.policy)
        candidate = SweepModelFits(model, fit, train)
        if len(model.causes) == 1:
            self.singles[model.causes[0]] = candidate
        return candidate, verdict

    def adopted(self, fitted: SweepModelFits, name: str | None) -> None:
        return None

    def alone(self, model: ModelSpec) -> SweepModelFits | None:
        return self.singles.get(model.causes[0]) if len(model.causes) == 1 else None


@dataclass
class SweepCauses:
    """What the selection across the sweep found."""

    base: SweepModelFits
    final: SweepModelFits
    steps: list[tuple[str, Verdict]]  # each cause named, with its step's verdict
    dropped: list[str]  # causes selected but of a different size on each step
    findings: list[Finding]
    per_step: dict[str, ShootingFit]  # each selected cause fitted with its own size per step

    @property
    def named(self) -> list[str]:
        """The causes named: selected, and of one size for every step."""
        return [name for name, _ in self.steps if name not in self.dropped]


def select_causes(
    ident: SweepIdentification, policy: SelectionPolicy, *, threads: int | None = None,
    progress: ProgressText | None = None, causes: Sequence[str] | None = None,
) -> SweepCauses:
    """The forward selection over the sweep, then each named cause's constancy across its
    steps (see the module's docstring); ``causes`` restricts the candidates (default: every
    cause that can show in a forced record)."""
    say = progress or (lambda message: None)
    data = ident.data
    lay = sweep_layouts(data)
    values = ident.fit.values
    hints = {name: values[name] for name in (q.theta_b_rad, q.offset_rad, q.eps)
             if name in values}
    say("fitting the baseline over every step")
    base_full = fit_on(data, BASELINE, values, hints, lay.full, ident.fit, ident.segments,
                       threads, REFINE_ITERATIONS)
    say(f"  rms {base_full.rms / data.noise_rad:.3g} x noise")
    base = SweepModelFits(BASELINE, base_full)
    names = [c.name for c in candidates_for(FORCED.name)
             if causes is None or c.name in causes]
    steps = SweepSteps(ident, lay, hints, names, threads, policy)
    final, taken = forward_selection(steps, base, None, policy, say)
    final = fitted_on(data, final, lay, threads, policy, say)
    dropped, findings, per_step = [], [], {}
    for name in [n for n, _ in taken]:
        fit, finding = size_per_step(data, final, name, lay, threads, say)
        per_step[name] = fit
        if finding is not None:
            dropped.append(name)
            findings.append(finding)
    return SweepCauses(base, final, taken, dropped, findings, per_step)


def fitted_on(data: SweepData, fitted: SweepModelFits, lay: SweepLayouts,
              threads: int | None, policy: SelectionPolicy, say: ProgressText
              ) -> SweepModelFits:
    """The final model with causes fitted on from where its step's iteration cap stopped
    it until it converges (at most the policy's ``rival_rounds`` more caps, as a single
    record's rivals): its parameters and their intervals are read at its optimum, which a
    step's cap (enough to judge a cause) need not reach."""
    fit = fitted.full
    if not fitted.model.causes:
        return fitted
    for _ in range(policy.rival_rounds):
        if fit.success:
            break
        fit = fit_on(data, fitted.model, fit.values, fit.values, lay.full, fit, lay.full,
                     threads, REFINE_ITERATIONS)
        say(f"  {fitted.model} fitted on (it had not converged): rms "
            f"{fit.rms / data.noise_rad:.4g} x noise, " + ", ".join(
                f"{spec.name} {_shown(fit.estimates[spec.name])}"
                for name in fitted.model.causes for spec in cause(name).parameters
                if spec.name in fit.estimates))
    return fitted if fit.rms > fitted.full.rms else replace(fitted, full=fit)


def _shown(estimate: Estimate) -> str:
    """'0.0685 [0.0671, 0.0699]'."""
    if estimate.ci95 is None:
        return f"{estimate.value:.4g}"
    return f"{estimate.value:.4g} [{estimate.ci95[0]:.4g}, {estimate.ci95[1]:.4g}]"


def size_per_step(
    data: SweepData, final: SweepModelFits, name: str, lay: SweepLayouts,
    threads: int | None, say: ProgressText,
) -> tuple[ShootingFit, Finding | None]:
    """The final model refitted with cause ``name``'s parameters of each step's own, and a
    ``constancy`` finding when they differ between the steps beyond their intervals."""
    sizes = [spec.name for spec in cause(name).parameters]
    say(f"  {name}: its size fitted step by step")
    fit = fit_on(data, final.model, final.full.values, final.full.values, lay.full,
                 final.full, lay.full, threads, REFINE_ITERATIONS, per_step=sizes)
    alpha = FALSE_ALARM / len(sizes)
    z_needed = float(stats.norm.isf(alpha / 2.0))
    parts, numbers = [], {"z_needed": z_needed}
    for size in sizes:
        estimates = [fit.estimates.get(step_name(size, n)) for n in data.numbers]
        kept = [(data.sweep.setting(s), e) for s, e in zip(data.sweep.steps, estimates,
                                                           strict=True)
                if e is not None and e.ci95 is not None and e.ci95[1] > e.ci95[0]]
        if len(kept) < 2:
            continue
        x = np.array([e.value for _, e in kept])
        spread = spread_across_steps(
            x, np.array([(e.ci95[1] - e.ci95[0]) / (2.0 * Z95) for _, e in kept]),
            np.array([s for s, _ in kept]))
        numbers |= {f"chi2_{size}": spread.chi2, f"slope_z_{size}": spread.slope_z}
        if spread.p < alpha:
            parts.append(f"its {size} {spread.how(data.sweep.parameter, z_needed)}, from "
                         f"{x[0]:.4g} on the first step to {x[-1]:.4g} on the last "
                         f"(chi-square {spread.chi2:.3g} on {spread.dof} degrees of freedom)")
    if not parts:
        return fit, None
    sentence = (f"{name} explains the steps only with a different size on each: "
                + "; ".join(parts) + "; an effect whose size changes with the drive is "
                "missing, and the cause is not named")
    return fit, Finding("constancy", sentence, numbers)


def causes_json(found: SweepCauses) -> dict[str, Any]:
    """The selection for the report's ``sweep`` section."""
    final = found.final.full
    steps = []
    for name, verdict in found.steps:
        params = {spec.name: final.estimates[spec.name].as_json()
                  for spec in cause(name).parameters if spec.name in final.estimates}
        steps.append({"cause": name, "parameters": params,
                      "named": name not in found.dropped,
                      "gain": {"information_criterion_delta":
                               verdict.information_criterion_delta,
                               "heldout_ratio": verdict.heldout_ratio},
                      "why": verdict.why,
                      "per_step": {k: e.as_json() for k, e in found.per_step[name].estimates.items()
                                   if STEP_MARK in k and k.split(STEP_MARK)[0] in params}})
    return {"named": found.named, "selected": steps,
            "baseline_rms_residual": found.base.full.rms,
            "final_rms_residual": final.rms,
            "final_model": list(found.final.model.causes)}
