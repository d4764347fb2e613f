"""The demo's analysis of its recordings: identification, regimes of the sweep steps, the
discrepancy analysis, the sweep explained as one, the model it arrives at, and the
bifurcation diagrams.

Each step calls the project's analysis (``analysis.identify``, ``analysis.dynamics``,
``analysis.discrepancy``); what lives here is only the demo's choice of what to run on
which record and how the results are combined.  The steps return the analysis's own results
and write no file: the report (rig.demo.report) writes them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis import quantities as q
from analysis.experiments import FORCED, FREE_DECAY, IMPACT_DECAY
from analysis.progress import ProgressText
from rig.demo.settings import NONE, DemoError, DemoSettings, indented

if TYPE_CHECKING:  # the analysis's result types, for the hints only (imported when run)
    from analysis.discrepancy import Analysis
    from analysis.identify import IdentificationResult
    from analysis.sweep.analyze import SweepAnalysis


def load_records(results: Mapping[str, Any], notes: list[str]) -> dict[str, Any]:
    """Decays as their longest gap-free stretch, the sweep one record per step."""
    from analysis.hdf5_records import load_hdf5_segments, load_hdf5_steps
    from recording.errors import RecordFormatError

    records: dict[str, Any] = {}
    for name in ("free_decay", "impact_decay"):
        segments = load_hdf5_segments(results[name].path)
        if len(segments) > 1:
            notes.append(
                f"{results[name].path.name}: {len(segments) - 1} gap(s); the longest gap-free "
                "stretch is analysed"
            )
        records[name] = max(segments, key=lambda r: r.time_s.size)
    try:
        records["sweep_steps"] = load_hdf5_steps(results["sweep"].path)
    except RecordFormatError as error:  # samples lost in a step's dwell: no regimes then
        notes.append(f"the sweep's steps cannot be analysed: {error}")
        records["sweep_steps"] = []
    return records


def identify(records: Mapping[str, Any], say: ProgressText) -> dict[str, IdentificationResult]:
    """The baseline model's identification: L, zeta from the free decay, then K, mu0 (and
    theta_b) from the impact decay with L and zeta held."""
    from analysis.identify import IdentificationError, fit_free_decay, fit_impact_decay

    try:
        free = fit_free_decay(records["free_decay"])
        say("  free decay: " + free.summary().splitlines()[1].strip())
        hold = {q.L_m: free[q.L_m].value, q.zeta: free[q.zeta].value}
        impact = fit_impact_decay(records["impact_decay"], hold=hold)
    except IdentificationError as error:
        raise DemoError(f"identification failed: {error}") from None
    say(
        f"  impact decay: K = {impact[q.K_N_per_m1_5].value:.4g} N/m^1.5, "
        f"mu0 = {impact[q.mu0_s_per_m].value:.3g} s/m"
    )
    return {"free_decay": free, "impact_decay": impact}


def combined_parameters(identified: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """L, omega, zeta from the free decay; K, E, R, mu0, theta_b from the impact decay."""
    out: dict[str, dict[str, Any]] = {}
    free, impact = identified["free_decay"], identified["impact_decay"]
    for key in (q.L_m, q.omega_rad_s, q.zeta):
        out[key] = free[key].as_json() | {"from": "free_decay"}
    for key in (q.K_N_per_m1_5, q.E_Pa, q.R_m, q.mu0_s_per_m, q.theta_b_rad):
        if key in impact.parameters:
            out[key] = impact[key].as_json() | {"from": "impact_decay"}
    return out


def classify_steps(steps: list[Any], say: ProgressText) -> tuple[list[dict[str, Any]], list[Any]]:
    """Regime of each step, judged from its strobe points locked to the tachometer (the same
    judgement as every measured record's), and each step's settled Poincare section."""
    from analysis.dynamics import judge_record_regime

    regimes, sections = [], []
    previous_beta = -math.inf
    for number, record in enumerate(steps):
        drive = record.drive
        beta = drive[q.amplitude_m] / record.rig_parameters().L_m
        direction = "up" if beta >= previous_beta else "down"
        previous_beta = beta
        entry: dict[str, Any] = {
            "step": number,
            "direction": direction,
            q.beta: beta,
            q.amplitude_m: drive[q.amplitude_m],
            q.frequency_hz: drive[q.frequency_hz],
            "duration_s": float(record.time_s[-1] - record.time_s[0]),
            "poincare_points": int(record.tach_indices.size),
        }
        section = np.zeros(0)
        try:
            noise, _ = _noise(record.angle_rad)
            regime, strobe = judge_record_regime(
                record.angle_rad, record.sample_rate_hz, noise,
                tach_indices=record.tach_indices, frequency_hz=drive[q.frequency_hz],
            )
            entry.update(kind=regime.kind, period=regime.period, label=regime.label)
            entry["short"] = regime.short_name
            entry["measured_frequency_hz"] = strobe.clock.frequency_hz
            transient = regime.evidence.get("transient_periods")
            entry["transient_s"] = regime.evidence.get("transient_s")
            # the settled part of a periodic step; every period of one that is not
            section = strobe.section[transient or 0 :]
        except ValueError as error:
            entry.update(kind="unclassified", period=None, label=f"unclassified: {error}")
            entry["short"] = "unclassified"
        sections.append(section)
        say(f"  step {number} ({direction}) beta {beta:.3g}: {entry['label']}")
        regimes.append(entry)
    return regimes, sections


def _noise(angle: np.ndarray) -> tuple[float, float]:
    from analysis.identify.preprocess import noise_and_quantum

    return noise_and_quantum(np.asarray(angle, dtype=float))


def analyse_discrepancies(
    records: Mapping[str, Any],
    regimes: list[dict[str, Any]],
    baseline: Mapping[str, Mapping[str, Any]],
    settings: DemoSettings,
    say: ProgressText,
    notes: list[str],
) -> dict[str, Analysis]:
    """The discrepancy analysis (analysis.discrepancy) on each decay, then on one sweep step
    started from the model the decays arrived at (``baseline`` when they found nothing)."""
    from analysis.discrepancy import AnalysisError, analyze_record

    chosen = {kind.name: records[kind.name] for kind in (FREE_DECAY, IMPACT_DECAY)}
    steps = records["sweep_steps"]
    if steps and settings.analyze_forced_step:
        chosen["forced_step"] = _forced_step_to_analyse(steps, regimes)
    findings: dict[str, Analysis] = {}
    for name, record in chosen.items():
        causes = None
        free_decay = findings.get(FREE_DECAY.name)
        found = free_decay.chosen if free_decay is not None else NONE
        if name == IMPACT_DECAY.name and settings.carry_free_decay_finding and found != NONE:
            causes = [found]
            notes.append(
                f"quick demo: the impact decay was checked for {found} only (what the free "
                "decay showed); the full demo tries every candidate cause"
            )
        priors = None
        if name == "forced_step":
            explained, _ = explained_parameters(baseline, findings)
            priors = {key: explained[key]["value"] for key in FORCED_PRIORS if key in explained}
        say(f"  {name}:" + (f" (candidates: {', '.join(causes)})" if causes else ""))
        try:
            analysis = analyze_record(
                record, progress=indented(say), causes=causes, priors=priors
            )
        except (AnalysisError, ValueError) as error:
            notes.append(f"discrepancy analysis of {name} failed: {error}")
            say(f"    failed: {error}")
            continue
        findings[name] = analysis
    return findings


def sweep_candidates(
    analyses: Mapping[str, Analysis], settings: DemoSettings, notes: list[str]
) -> list[str] | None:
    """The causes the sweep is checked for: in the quick demo, what the free decay found
    (when that can show in a forced record; a note says so); else every candidate."""
    from analysis.discrepancy.candidates import candidates_for

    free_decay = analyses.get(FREE_DECAY.name)
    found = free_decay.chosen if free_decay is not None else NONE
    if not settings.carry_free_decay_finding or found not in {
        c.name for c in candidates_for(FORCED.name)
    }:
        return None
    notes.append(
        f"quick demo: the sweep was checked for {found} only (what the free decay showed); "
        "the full demo tries every candidate cause"
    )
    return [found]


FORCED_PRIORS = (q.omega_rad_s, q.zeta, q.K_N_per_m1_5, q.mu0_s_per_m)


def _forced_step_to_analyse(steps: list[Any], regimes: list[dict[str, Any]]):
    """A settled periodic step: the lowest period, then the smallest drive, preferring the way
    down (longer settled); else the first step."""
    periodic = [
        (r["period"], r["direction"] != "down", r[q.beta], r["step"])
        for r in regimes
        if r["kind"] == "periodic"
    ]
    return steps[min(periodic)[-1]] if periodic else steps[0]


def bifurcation_diagrams(
    model,
    settings: DemoSettings,
    regimes: list[dict[str, Any]],
    sections: list[np.ndarray],
    say: ProgressText,
):
    """Simulated (the identified model, continuation up and down) and measured diagrams."""
    from analysis.dynamics import bifurcation_from_recording, simulate_bifurcation

    betas = np.linspace(
        min(settings.sweep_betas) * 0.5, max(settings.sweep_betas) * 1.04, settings.simulated_betas
    )
    say(
        f"  simulating {betas.size} beta values x {settings.simulated_periods} periods, "
        "up and down"
    )
    simulated = simulate_bifurcation(
        model,
        betas,
        periods=settings.simulated_periods,
        record_periods=settings.simulated_record_periods,
        mode="continuation",
    )
    diagrams = simulated
    if regimes:
        measured = bifurcation_from_recording([r[q.beta] for r in regimes], sections)
        diagrams = (*simulated, measured)
    return diagrams


def identified_model(
    parameters: Mapping[str, Mapping[str, Any]],
    rig,
    frequency_hz: float,
    causes: Mapping[str, Mapping[str, float]] | None = None,
):
    """The model with identified L, zeta, K, mu0 (and theta_b) on the recording's rig constants
    (m, l, R, g: ``rig``), the found causes switched on, driven at ``frequency_hz``."""
    from analysis.model import Drive, Model

    values = {
        key: parameters[key]["value"]
        for key in (q.L_m, q.zeta, q.mu0_s_per_m, q.theta_b_rad)
        if key in parameters
    }
    fitted = rig.with_values(**values).with_stiffness(parameters[q.K_N_per_m1_5]["value"])
    model = Model(rig=fitted, drive=Drive(amplitude_m=0.0, frequency_hz=frequency_hz))
    for name, cause_values in (causes or {}).items():
        model = model.with_extension(name, **cause_values)
    return model


def explained_parameters(
    baseline: Mapping[str, Mapping[str, Any]], findings: Mapping[str, Analysis]
) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, float]]]:
    """Parameters of the model the discrepancy analysis arrived at, and the causes it added.

    L, omega, zeta come from the free decay's extended fit, K, E, mu0, theta_b from the
    impact decay's (each record's own finding); without a finding, the baseline's values.
    Each cause takes its parameters from the record that found it (the impact decay first).
    A forced record's finding is reported but not merged: its fit starts from the decays'
    values and judges a short steady state, so it refines what they found rather than
    founding the model.
    """
    from analysis.extensions import NONE as NO_CAUSE
    from analysis.extensions import cause

    out = {key: dict(value) for key, value in baseline.items()}
    sources = {
        FREE_DECAY.name: (q.L_m, q.omega_rad_s, q.zeta),
        IMPACT_DECAY.name: (q.K_N_per_m1_5, q.E_Pa, q.mu0_s_per_m, q.theta_b_rad),
    }
    causes: dict[str, dict[str, float]] = {}
    for name in (IMPACT_DECAY.name, FREE_DECAY.name):
        analysis = findings.get(name)
        if analysis is None:
            continue
        extended = analysis.extended_parameters()
        for key in sources.get(name, ()):
            if key in extended:
                out[key] = {**extended[key], "from": f"{name}, extended model"}
        found = analysis.chosen
        if found != NO_CAUSE and found not in causes:
            names = [spec.name for spec in cause(found).parameters]
            causes[found] = {k: extended[k]["value"] for k in names if k in extended}
            for k in names:
                if k in extended:
                    out[k] = {**extended[k], "from": f"{name}, extended model"}
    return out, causes


def explain_sweep(
    path: Any, say: ProgressText, notes: list[str], causes: list[str] | None = None
) -> SweepAnalysis | None:
    """The sweep explained as one (``analysis.sweep.analyze_sweep``): one rig for every
    step, the causes that hold across the steps (``causes``: only these candidates), and,
    when the analysis compares them, the baseline's and the explained model's diagrams with
    the measured one.  None (with a note) when the sweep cannot be explained."""
    from analysis.sweep.analyze import analyze_sweep
    from analysis.sweep.load import load_sweep
    from recording.errors import RecordFormatError

    try:
        return analyze_sweep(load_sweep([path]), threads=1, progress=indented(say),
                             causes=causes)
    except (RecordFormatError, ValueError) as error:
        notes.append(f"the sweep cannot be explained as one: {error}")
        return None

