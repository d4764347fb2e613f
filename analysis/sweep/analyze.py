"""The analysis of a sweep: one rig identified for every step, each step's drive and fit,
the steps set aside, and whether the parameters the steps see alone hold across the sweep.

What it reports is the JSON report's ``sweep`` section (docs/MODEL.md, "The sweep
section"); :func:`report_json` adds the source, the policy and the warnings around it.

A parameter that the steps, each fitted alone, put at different values beyond their
intervals does not hold across the sweep: the one value the joint fit gives it is a
compromise, and how the step values vary with the swept setting (a trend, or not) is
reported as a ``constancy`` residual finding, the size an effect the model lacks would
need (for example "theta_b_rad grows with the amplitude").  The test: the step values'
scatter about their weighted mean, chi-square on the steps' standard errors (from their
95 % intervals, on the fit's scale: the log for a parameter fitted as a log), against the
FALSE_ALARM quantile divided among the parameters compared (Bonferroni); the trend is the
weighted line through the values against the setting, named when its slope's z passes the
same threshold.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.residual_reading import Finding
from analysis.dynamics.lines import FALSE_ALARM
from analysis.identify.forced import BASELINE_PLANS
from analysis.identify.intervals import Z95
from analysis.identify.result import Estimate
from analysis.sweep.causes import SweepCauses, causes_json, select_causes
from analysis.sweep.constancy import spread_across_steps
from analysis.sweep.fit import (
    SweepIdentification,
    identify_sweep,
    shared_json,
    sweep_data,
)
from analysis.sweep.steps import Sweep

Progress = Callable[[str], None]
MIN_STEPS = 3  # a parameter is compared across at least this many steps with intervals
# the identification's parameters fitted as logs (their steps' scatter is compared there)
LOG_SCALE = {name for name, (_, log, _, _) in BASELINE_PLANS.items() if log}


@dataclass
class SweepAnalysis:
    """What the analysis of a sweep found, before it becomes the report."""

    sweep: Sweep
    ident: SweepIdentification
    policy: SelectionPolicy
    causes: SweepCauses
    findings: list[Finding]
    timings: dict[str, float]
    # Hook for the diagram comparison (analysis.sweep.diagram, added by the lead): the
    # measured, baseline and explained bifurcation diagrams compared step by step, as the
    # report's ``sweep.diagram``; None until that comparison runs.
    diagram: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)


def analyze_sweep(
    sweep: Sweep, *, threads: int | None = None, progress: Progress | None = None,
    policy: SelectionPolicy = DEFAULT_POLICY,
) -> SweepAnalysis:
    """Identify one rig for every step of ``sweep`` and check that its parameters hold
    across the steps (see the module's docstring)."""
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    n = len(sweep.steps)
    say(f"sweep of {n} steps over the drive's {sweep.parameter}"
        + (f" ({len(sweep.set_aside)} set aside)" if sweep.set_aside else ""))
    data = sweep_data(sweep)
    for step, regime in zip(sweep.steps, data.regimes, strict=True):
        say(f"  step {step.number}: {sweep.setting(step):.4g} "
            f"{'m' if sweep.parameter == 'amplitude' else 'Hz'}, regime {regime}")
    ident = identify_sweep(data, progress=say, threads=threads)
    timings = {"identification": time.perf_counter() - clock}
    say("causes across the sweep, each of one size for every step")
    causes = select_causes(ident, policy, threads=threads, progress=say)
    timings["causes"] = time.perf_counter() - clock - timings["identification"]
    findings = [f for f in (constancy_across_steps(ident),) if f is not None] + \
        causes.findings
    warnings = []
    misfit = max(ident.step_rms(k) / d.noise_rad for k, d in enumerate(data.steps))
    if misfit > 3.0:
        warnings.append(f"poor fit: on some step the residual is {misfit:.3g} x that step's "
                        "noise; one rig with these parameters does not explain every step")
    return SweepAnalysis(sweep, ident, policy, causes, findings, timings, warnings=warnings)


def step_values(ident: SweepIdentification, name: str) -> list[tuple[int, float, Estimate]]:
    """Parameter ``name`` as each step fitted alone gives it: (step index, setting,
    estimate), for the steps that give it an interval."""
    sweep = ident.data.sweep
    out = []
    for k, (step, alone) in enumerate(zip(sweep.steps, ident.alone, strict=True)):
        estimate = alone.short_fit.estimates.get(name)
        if estimate is not None and estimate.ci95 is not None:
            out.append((k, sweep.setting(step), estimate))
    return out


def constancy_across_steps(ident: SweepIdentification) -> Finding | None:
    """A ``constancy`` finding when some shared parameter's step values (each step fitted
    alone) differ beyond their intervals, with how they vary with the setting; None when
    they agree (see the module's docstring)."""
    tests = {}
    for name in (n for n in ident.fit.estimates if "@" not in n):
        values = step_values(ident, name)
        if len(values) < MIN_STEPS:
            continue
        x, se, setting = _on_scale(name, values)
        if np.all(se > 0):
            tests[name] = (spread_across_steps(x, se, setting), values)
    if not tests:
        return None
    alpha = FALSE_ALARM / len(tests)
    differing = {n: t for n, t in tests.items() if t[0].p < alpha}
    if not differing:
        return None
    z_needed = float(stats.norm.isf(alpha / 2.0))
    parts, numbers = [], {"z_needed": z_needed}
    for name, (spread, values) in differing.items():
        parts.append(f"{name} {spread.how(ident.data.sweep.parameter, z_needed)}: "
                     f"{values[0][2].value:.4g} on the first step, {values[-1][2].value:.4g} "
                     f"on the last (chi-square {spread.chi2:.3g} on {spread.dof} degrees of "
                     "freedom)")
        numbers |= {f"chi2_{name}": spread.chi2, f"slope_z_{name}": spread.slope_z}
    sentence = ("fitted step by step, " + "; ".join(parts) + ": one rig with one value of "
                "each does not explain every step, an effect that changes with the drive "
                "is missing")
    return Finding("constancy", sentence, numbers)


def _on_scale(name: str, values: list[tuple[int, float, Estimate]]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Values and standard errors on the fit's scale, and the settings."""
    if name in LOG_SCALE:
        x = np.array([math.log(e.value) for _, _, e in values])
        se = np.array([math.log(e.ci95[1] / e.ci95[0]) / (2.0 * Z95) for _, _, e in values])
    else:
        x = np.array([e.value for _, _, e in values])
        se = np.array([(e.ci95[1] - e.ci95[0]) / (2.0 * Z95) for _, _, e in values])
    return x, se, np.array([s for _, s, _ in values])


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
            "setting": sweep.setting(step), "frequency_hz": step.frequency_hz,
            "amplitude_m": step.amplitude_m, "settle_s": step.settle_s,
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
    omega = fit.estimates["omega_rad_s"]
    g = data.steps[0].rig.g_m_s2
    length = {"value": g / omega.value ** 2}
    if omega.ci95 is not None and omega.ci95[0] > 0:
        length["ci95"] = [g / omega.ci95[1] ** 2, g / omega.ci95[0] ** 2]
    return {
        "source": sweep.source,
        "parameter": sweep.parameter,
        "steps": steps,
        "set_aside": [{"step": s.number, "reason": s.reason} for s in sweep.set_aside],
        "shared": {"L_m": length, **shared_json(fit)},
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
