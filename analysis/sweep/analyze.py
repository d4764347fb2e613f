"""The analysis of a sweep: one rig identified for every step
(:mod:`analysis.sweep.fit`), the causes that hold across the steps
(:mod:`analysis.sweep.causes`), each step's drive and fit, and the steps set aside.

What it reports is the JSON report's ``sweep`` section (docs/MODEL.md, "The sweep
section"); :func:`report_json` adds the policy and the warnings around it.  Each step
identified alone is reported beside the joint fit (``alone``), to read, not to judge:
over one short dwell a cold start's short segments can trade the barrier against the
sensor's zero, and their scatter from step to step is no finding (a clean reference
sweep's steps put them 3 mrad apart, in opposite directions, at 4.7 standard errors).

The gain where a lab looks (:func:`compare_with_measured`): the baseline (the shared rig,
no cause) and the explained model (the rig with the causes named) are run through the
sweep as the rig ran it, each step with its measured drive
(:mod:`analysis.sweep.diagram`), and their bifurcation diagrams compared with the
measured one step by step: the report's ``sweep.diagram``.  When no cause is named the
explained model is the baseline, and it is compared once.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.residual_reading import Finding
from analysis.model import Drive, Model
from analysis.model_values import model_from_values
from analysis.progress import ProgressText
from analysis.sweep.causes import SweepCauses, causes_json, select_causes
from analysis.sweep.diagram import (
    DiagramComparison,
    JudgedStep,
    compare_diagrams,
    judge_measured,
)
from analysis.sweep.fit import (
    StepsNotIdentifiedError,
    SweepData,
    SweepIdentification,
    identify_sweep,
    shared_json,
    step_name,
    sweep_data,
)
from analysis.sweep.steps import Sweep

RunMap = Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]]
# Where a simulated sweep starts when its fit did not reach the first dwell's first
# sample: the pendulum at rest at the first settle's start, drive phase 0.
REST = (0.0, 0.0)
BASELINE_NAME = "baseline"
EXPLAINED_NAME = "explained model"


@dataclass(frozen=True)
class SweepDiagram:
    """The measured diagram against the baseline's and the explained model's.

    ``explained`` is None when no cause is named (the explained model is the baseline);
    ``models`` the models simulated, by name."""

    measured: tuple[JudgedStep, ...]
    baseline: DiagramComparison
    explained: DiagramComparison | None
    named: tuple[str, ...]
    models: dict[str, Model]
    sweep: Sweep  # the sweep the models ran through
    start: str  # where they started: 'first dwell' or 'rest'


    @property
    def comparisons(self) -> list[DiagramComparison]:
        """The comparisons made: the baseline's, then the explained model's if any."""
        return [self.baseline] + ([self.explained] if self.explained is not None else [])

    def summary(self) -> str:
        """'baseline: 6 of 16 steps agree, the first period-doubling at beta 0.083 against
        0.099 measured; explained model: 15 of 16 steps agree, ...'."""
        if self.explained is None:
            return (self.baseline.summary() + "; no cause named: the explained model is the "
                    "baseline")
        return f"{self.baseline.summary()}; {self.explained.summary()}"

    def as_json(self) -> dict[str, Any]:
        """The report's ``sweep.diagram`` (docs/MODEL.md, "The sweep section")."""
        return {"start": self.start, "named": list(self.named),
                "explained_is_baseline": self.explained is None,
                "baseline": self.baseline.as_json(),
                "explained": None if self.explained is None else self.explained.as_json(),
                "summary": self.summary()}


@dataclass
class SweepAnalysis:
    """What the analysis of a sweep found, before it becomes the report."""

    sweep: Sweep
    ident: SweepIdentification
    policy: SelectionPolicy
    causes: SweepCauses
    findings: list[Finding]
    timings: dict[str, float]
    # The baseline's and the explained model's diagrams compared with the measured one
    # step by step (SweepDiagram.as_json), the report's ``sweep.diagram``; None when
    # analyze_sweep was told not to compare them.
    diagram: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)
    # The diagrams themselves (samples and clouds, for the figures); None when not compared.
    diagrams: SweepDiagram | None = None


def step_drives(ident: SweepIdentification, values: dict[str, float]) -> list[Drive]:
    """Each step's measured drive as a model runs it: the stated amplitude, a pure sine,
    at the frequency measured on the step (or fitted as its own, ``drive_frequency_hz@N``);
    the model's drive causes shape it."""
    return [d.drive.model_drive(values.get(step_name(q.drive_frequency_hz, n)))
            for d, n in zip(ident.data.steps, ident.data.numbers, strict=True)]


def compare_with_measured(
    ident: SweepIdentification, causes: SweepCauses, *, run_map: RunMap | None = None,
) -> SweepDiagram:
    """The baseline and the explained model (the rig with the causes named, of one size
    for every step) through the sweep as the rig ran it, each step at its measured drive,
    against the measured diagram; ``run_map`` spreads the simulations over workers
    (``analysis.maps.MapRunner.map``) with the same figures wherever they ran."""
    data = ident.data
    rig = data.steps[0].rig
    named = tuple(causes.named)
    fits = [(BASELINE_NAME, causes.base.full.values, causes.base.model.causes)]
    if named:
        # the final fit's values; a cause selected but not named (its size differs from
        # step to step) is left out of the model compared
        fits.append((EXPLAINED_NAME, causes.final.full.values,
                     tuple(c for c in causes.final.model.causes if c not in causes.dropped)))
    measured = judge_measured(data.sweep)
    models, drives, cases = {}, [], []
    started = {_first_state(ident, fit) is not None
               for fit in [causes.base.full] + ([causes.final.full] if named else [])}
    from_dwell = started == {True}
    for (name, values, switched_on), fit in zip(fits, (causes.base.full, causes.final.full),
                                                strict=False):
        drives.append(step_drives(ident, values))
        model = model_from_values(rig, drives[-1][0], True, values, switched_on)
        models[name] = model
        if from_dwell:
            # the fitted state and drive phase at the first dwell's first sample, the
            # first settle (already run by the rig) not simulated
            first = data.sweep.steps[0]
            sweep = replace(data.sweep, steps=(replace(first, settle_s=0.0),
                                               *data.sweep.steps[1:]))
            phase = values.get(step_name(q.drive_phase_rad, data.numbers[0]),
                               data.steps[0].drive.phase0_rad)
            cases.append((name, model, sweep, measured, _first_state(ident, fit), phase))
        else:
            cases.append((name, model, data.sweep, measured, REST, 0.0))
    compared = compare_diagrams([case[:5] for case in cases], run_map, drives=drives,
                                start_phases=[case[5] for case in cases])
    return SweepDiagram(measured, compared[0], compared[1] if named else None, named, models,
                        data.sweep, "first dwell" if from_dwell else "rest")


def _first_state(ident: SweepIdentification, fit: Any) -> tuple[float, float] | None:
    """The fit's true state (theta, theta') at the first dwell's first sample; None when
    no fitted segment starts there."""
    first = ident.data.step_slice(0).start
    theta, rate = float(fit.true_angle[first]), float(fit.rate[first])
    return (theta, rate) if math.isfinite(theta) and math.isfinite(rate) else None


def analyze_sweep(
    sweep: Sweep, *, threads: int | None = None, progress: ProgressText | None = None,
    policy: SelectionPolicy = DEFAULT_POLICY, diagram: bool = True,
    run_map: RunMap | None = None, causes: Sequence[str] | None = None,
) -> SweepAnalysis:
    """Identify one rig for every step of ``sweep``, select the causes that hold across
    its steps (``causes`` restricts the candidates; default: every cause that can show in
    a forced record) and (``diagram``) compare the baseline's and the explained model's
    diagrams with the measured one, their simulations spread by ``run_map`` (see the
    module's docstring)."""
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    n = len(sweep.steps)
    say(f"sweep of {n} steps over the drive's {sweep.parameter}"
        + (f" ({len(sweep.set_aside)} set aside)" if sweep.set_aside else ""))
    sweep, data, ident = _identified(sweep, say, threads)
    timings = {"identification": time.perf_counter() - clock}
    say("causes across the sweep, each of one size for every step")
    causes = select_causes(ident, policy, threads=threads, progress=say, causes=causes)
    timings["causes"] = time.perf_counter() - clock - timings["identification"]
    findings = list(causes.findings)
    warnings = []
    misfit = max(ident.step_rms(k) / d.noise_rad for k, d in enumerate(data.steps))
    if misfit > 3.0:
        warnings.append(f"poor fit: on some step the residual is {misfit:.3g} x that step's "
                        "noise; one rig with these parameters does not explain every step")
    analysis = SweepAnalysis(sweep, ident, policy, causes, findings, timings,
                             warnings=warnings)
    if diagram:
        say("the baseline's and the explained model's diagrams against the measured one")
        clock = time.perf_counter()
        diagrams = compare_with_measured(ident, causes, run_map=run_map)
        timings["diagram"] = time.perf_counter() - clock
        analysis.diagrams = diagrams
        analysis.diagram = diagrams.as_json()
        say("  " + diagrams.summary())
    return analysis


def _identified(sweep: Sweep, say: ProgressText, threads: int | None
                ) -> tuple[Sweep, SweepData, SweepIdentification]:
    """The sweep's rig identified once for every step; a step that is no forced record fit
    for a fit, or that cannot be identified alone, is set aside with the reason and the
    rest identified again (a lone step's fit put a barrier at 0.57 rad, out of range, and
    failed the whole sweep)."""
    while True:
        try:
            data = sweep_data(sweep)
            for step, regime in zip(sweep.steps, data.regimes, strict=True):
                say(f"  step {step.number}: {sweep.setting(step):.4g} "
                    f"{'m' if sweep.parameter == 'amplitude' else 'Hz'}, regime {regime}")
            return sweep, data, identify_sweep(data, progress=say, threads=threads)
        except StepsNotIdentifiedError as failed:
            for number, why in failed.reasons.items():
                say(f"  step {number} set aside: {why}")
            sweep = sweep.setting_aside(failed.reasons)


def sweep_json(analysis: SweepAnalysis) -> dict[str, Any]:
    """The report's ``sweep`` section (docs/MODEL.md, "The sweep section")."""
    ident = analysis.ident
    data = ident.data
    sweep = analysis.sweep
    steps = []
    final = analysis.causes.final.full
    for k, (step, d) in enumerate(zip(sweep.steps, data.steps, strict=True)):
        rms = ident.step_rms(k)
        r = final.residual[data.step_slice(k)]
        r = r[np.isfinite(r)]
        final_rms = float(math.sqrt(np.mean(r * r))) if r.size else math.nan
        steps.append({
            "step": step.number, "direction": step.direction,
            "setting": sweep.setting(step), q.frequency_hz: step.frequency_hz,
            q.amplitude_m: step.amplitude_m, "settle_s": step.settle_s,
            "dwell_s": float(d.t[-1]), "regime": data.regimes[k],
            "drive": d.drive.as_json(),
            "own": {name: e.as_json() for name, e in ident.step_estimates(k).items()},
            "alone": {name: e.as_json() for name, e in
                      ident.alone[k].short_fit.estimates.items()},
            "noise_rad": d.noise_rad, "rms_residual": rms,
            "rms_over_noise": rms / d.noise_rad,
            "explained_rms_over_noise": final_rms / d.noise_rad,
        })
    fit = ident.fit
    omega = fit.estimates[q.omega_rad_s]
    g = data.steps[0].rig.g_m_s2
    length = {"value": g / omega.value ** 2}
    if omega.ci95 is not None and omega.ci95[0] > 0:
        length["ci95"] = [g / omega.ci95[1] ** 2, g / omega.ci95[0] ** 2]
    return {
        "source": sweep.source,
        "parameter": sweep.parameter,
        "steps": steps,
        "set_aside": [{"step": s.number, "reason": s.reason} for s in sweep.set_aside],
        "shared": {q.L_m: length, **shared_json(fit)},
        "model": list(ident.model.causes),
        "cause": (analysis.causes.named or ["none"])[0],
        "causes": causes_json(analysis.causes),
        "noise_rad": data.noise_rad,
        "rms_residual": fit.rms,
        "fit": {"segments": ident.segments.segments.count, "iterations": fit.iterations,
                "solver": fit.message, "success": fit.success,
                "robust": data.heavy_tailed},
        "residual_findings": [f.as_json() for f in analysis.findings],
        "diagram": analysis.diagram,
        "timings_s": dict(analysis.timings),
    }


def report_json(analysis: SweepAnalysis) -> dict[str, Any]:
    """The JSON report of a sweep: its ``sweep`` section with the policy and warnings."""
    return {"experiment": "forced", "kind": "sweep", "sweep": sweep_json(analysis),
            "policy": analysis.policy.as_json(), "warnings": list(analysis.warnings)}
