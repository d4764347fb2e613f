"""Identification and explanation of a recording, for the analysis panel.

Pure computation (no Qt): the panel runs :func:`identify_recording` (the baseline fit and
the model's response) or :func:`explain_recording` (the discrepancy analysis) on a worker
thread; :func:`explanation_lines` says what the analysis found in the GUI's units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.estimate_text import estimate_text
from analysis.experiments import FREE_DECAY
from analysis.identify import IdentificationResult, fit_drive, fit_free_decay, fit_impact_decay
from analysis.identify.free_decay import averaging_solution, simulated_free_decay
from analysis.model import Drive, Model, table_displacement
from analysis.progress import ProgressText
from analysis.record_loaders import load_record
from analysis.records import Record
from gui.units import DISPLAY, parameter_unit

GAIN_NAMES = {
    "information_criterion_delta": "information criterion gain",
    "heldout_ratio": "held-out error ratio",
    "invariant_ratio": "invariant statistics ratio",
}


@dataclass(frozen=True)
class ModelOverlay:
    """What was measured, what the identified model says, and the identification report."""

    source: str
    quantity: str  # "angle" (rad) or "table" (m)
    time_s: np.ndarray
    measured: np.ndarray
    model_time_s: np.ndarray
    model: np.ndarray
    result: IdentificationResult

    @property
    def rms_difference(self) -> float:
        """RMS of measured minus model where the model is drawn."""
        on_model = np.interp(self.model_time_s, self.time_s, self.measured)
        return float(np.sqrt(np.mean((on_model - self.model) ** 2)))


def _load(path: str | Path, experiment: str | None) -> Record:
    """The record, as the experiment ``experiment`` when one is given (else as it states)."""
    record = load_record(path)
    if experiment and experiment != record.experiment:
        record = replace(record, experiment=experiment)
    return record


@dataclass(frozen=True)
class Explanation:
    """What ``analyze`` found (its JSON report) and the curves to draw: the angle fitted, the
    baseline's response and the extended model's (None when no cause was tried)."""

    report: dict[str, Any]
    time_s: np.ndarray
    measured_rad: np.ndarray
    baseline_rad: np.ndarray
    extended_rad: np.ndarray | None
    extended_label: str


def explain_recording(
    path: str | Path,
    experiment: str | None = None,
    progress: ProgressText | None = None,
) -> Explanation:
    """Run ``analyze`` on a recording: its JSON report (analysis.report) and model curves.

    One worker, in this thread: a process pool forked from the GUI's threads is unsafe.
    """
    from analysis.discrepancy import analyze_record
    from analysis.report.discrepancy import report_json

    analysis = analyze_record(_load(path, experiment), workers=1, progress=progress)
    baseline, extended = analysis.model_curves()
    shown = analysis.shown_model
    adopted = analysis.final_outcome is not None
    label = "" if shown is None else shown.model.name
    return Explanation(
        report=report_json(analysis),
        time_s=np.asarray(analysis.data.t, dtype=float),
        measured_rad=np.where(analysis.data.valid, analysis.data.y, np.nan),
        baseline_rad=np.asarray(baseline, dtype=float),
        extended_rad=None if extended is None else np.asarray(extended, dtype=float),
        extended_label=f"baseline + {label}" + ("" if adopted else " (not adopted)"),
    )


def _parameter_line(name: str, estimate: dict[str, Any]) -> str:
    """``name = value 95% CI [..] unit`` in the display unit its SI suffix names."""
    value, ci95 = estimate["value"], estimate.get("ci95")
    named = parameter_unit(name)
    if named is None:
        return f"{name} = {estimate_text(value, ci95, '.4g')}"
    symbol, unit = named
    shown_ci = None if ci95 is None else [None if v is None else unit.show(v) for v in ci95]
    return f"{symbol} = {estimate_text(unit.show(value), shown_ci, '.4g')} {unit.unit}"


def _gain_line(gain: dict[str, Any]) -> str:
    """The gain of a cause's step, every measure the analysis gave."""
    parts = [f"{GAIN_NAMES.get(key, key)} {value:.3g}"
             for key, value in gain.items() if value is not None]
    return "gain: " + ("; ".join(parts) if parts else "none measured")


def explanation_lines(report: dict[str, Any]) -> list[str]:
    """What the analysis found, in the GUI's units: the causes with their parameters and
    gain, the residual before and after, the findings, the regime and the cautions."""
    causes = report["causes"]
    if not causes:
        lines = [f"cause: {report['cause']} (no cause earns its keep over the baseline)"]
    else:
        lines = [("causes: " if len(causes) > 1 else "cause: ")
                 + " + ".join(c["cause"] for c in causes)]
    for step in causes:
        lines.append(f"{step['cause']}:")
        lines += [f"    {_parameter_line(name, estimate)}"
                  for name, estimate in step["parameters"].items()]
        lines.append(f"    {_gain_line(step['gain'])}")
    angle = DISPLAY["angle"]
    noise = report["noise_rad"]
    after = "with " + " + ".join(c["cause"] for c in causes) if causes else "unchanged"
    for label, rms in (("before (baseline)", report["baseline"]["rms_residual"]),
                       (f"after ({after})", report["extended"]["rms_residual"])):
        ratio = f" = {rms / noise:.3g} x the noise" if noise else ""
        lines.append(f"residual {label}: {angle.show(rms):.3g} {angle.unit} rms{ratio}")
    if noise:
        lines.append(f"noise: {angle.show(noise):.3g} {angle.unit} rms")
    if report.get("regime"):
        lines.append(f"regime: {report['regime']['label']}")
    if report.get("unexplained"):
        lines.append("the model still misses something: see the residual findings")
    lines += [f"residual finding ({f['kind']}): {f['text']}"
              for f in report.get("residual_findings", [])]
    lines += [f"caution: {warning}" for warning in report.get("warnings", [])]
    return lines


def identify_recording(path: str | Path, experiment: str | None = None) -> ModelOverlay:
    """Identify a recording (its experiment decides the fit) and compute the model's response.

    ``experiment`` overrides the one the file states (a GUI recording is 'forced' by
    default, but the operator may have recorded a decay).
    """
    record = _load(path, experiment)
    t = record.time_s - record.time_s[0]
    if record.kind is FREE_DECAY:
        result = fit_free_decay(record)
        model_t, model = _free_decay_response(record, t, result)
        return ModelOverlay(str(path), "angle", t, record.angle_rad, model_t, model, result)
    if not record.kind.driven:
        result = fit_impact_decay(record)
        model_t, model = _impact_decay_response(record, t, result)
        return ModelOverlay(str(path), "angle", t, record.angle_rad, model_t, model, result)
    result = fit_drive(record)
    amplitude = result[q.amplitude_m].value
    phase = result["phase_rad"].value
    omega = 2.0 * math.pi * result[q.frequency_hz].value
    sine = table_displacement(omega * t + phase, amplitude, 0.0, 0.0)  # the fundamental
    table = np.asarray(record.table_m, dtype=float)
    sine += float(np.nanmean(table - sine))
    return ModelOverlay(str(path), "table", t, table, t, sine, result)


def _fitted_span(t: np.ndarray, result: IdentificationResult) -> np.ndarray:
    """Where the fit applies: from the detected release to where the pendulum came to rest."""
    start = float(result.details.get("release_trim_s", 0.0))
    end = t[-1] - float(result.details.get("rest_trim_s", 0.0))
    return (t >= start - 1e-12) & (t <= end + 1e-12)


def _free_decay_response(
    record: Record, t: np.ndarray, result: IdentificationResult
) -> tuple[np.ndarray, np.ndarray]:
    fitted = result.details["fitted"]
    span = _fitted_span(t, result)
    model_t = t[span]
    local = model_t - model_t[0]
    if "amplitude_rad" in fitted:
        model = averaging_solution(
            local,
            fitted["amplitude_rad"],
            fitted["phase_rad"],
            fitted[q.zeta],
            fitted[q.omega_rad_s],
            fitted[q.offset_rad],
        )
    else:
        model = (
            simulated_free_decay(
                local,
                fitted[q.theta0_rad],
                fitted[q.theta_dot0_rad_s],
                fitted[q.zeta],
                fitted[q.omega_rad_s],
                record.gravity_m_s2,
            )
            + fitted[q.offset_rad]
        )
    return model_t, model


def _impact_decay_response(
    record: Record, t: np.ndarray, result: IdentificationResult
) -> tuple[np.ndarray, np.ndarray]:
    from analysis.simulate import SimulationSettings, simulate

    fitted = result.details["fitted"]
    p = result.parameters
    rig = record.rig_parameters(
        L_m=p[q.L_m].value,
        zeta=p[q.zeta].value,
        g_m_s2=record.gravity_m_s2,
        mu0_s_per_m=p[q.mu0_s_per_m].value,
        theta_b_rad=p[q.theta_b_rad].value,
    ).with_stiffness(p[q.K_N_per_m1_5].value)
    span = _fitted_span(t, result)
    model_t = t[span]
    fs = 1.0 / float(t[1] - t[0])
    run = simulate(
        Model(rig=rig, drive=Drive(), barrier=True),
        fitted[q.theta0_rad],
        fitted[q.theta_dot0_rad_s],
        settings=SimulationSettings(duration_s=model_t.size / fs, fs_hz=fs, poincare_phase=None),
    )
    theta = np.asarray(run.theta, dtype=float)[: model_t.size]
    return model_t[: theta.size], theta + fitted[q.offset_rad]
