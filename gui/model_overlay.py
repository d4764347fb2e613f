"""Identification of a recording and the identified model's response, for the analysis panel.

Pure computation (no Qt): the panel runs :func:`identify_recording` on a worker thread
and draws the measured and the model's curves on top of each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from analysis.experiments import FREE_DECAY
from analysis.identify import IdentificationResult, fit_drive, fit_free_decay, fit_impact_decay
from analysis.identify.free_decay import averaging_solution, simulated_free_decay
from analysis.model import Drive, Model
from analysis.record_loaders import load_record
from analysis.records import Record


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


def identify_recording(path: str | Path, experiment: str | None = None) -> ModelOverlay:
    """Identify a recording (its experiment decides the fit) and compute the model's response.

    ``experiment`` overrides the one the file states (a GUI recording is 'forced' by
    default, but the operator may have recorded a decay).
    """
    record = load_record(path)
    if experiment and experiment != record.experiment:
        record = replace(record, experiment=experiment)
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
    amplitude = result["amplitude_m"].value
    phase = result["phase_rad"].value
    omega = 2.0 * math.pi * result["frequency_hz"].value
    sine = amplitude * np.sin(omega * t + phase)
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
            fitted["zeta"],
            fitted["omega_rad_s"],
            fitted["offset_rad"],
        )
    else:
        model = (
            simulated_free_decay(
                local,
                fitted["theta0_rad"],
                fitted["theta_dot0_rad_s"],
                fitted["zeta"],
                fitted["omega_rad_s"],
                record.gravity_m_s2,
            )
            + fitted["offset_rad"]
        )
    return model_t, model


def _impact_decay_response(
    record: Record, t: np.ndarray, result: IdentificationResult
) -> tuple[np.ndarray, np.ndarray]:
    from analysis.simulate import SimulationSettings, simulate

    fitted = result.details["fitted"]
    p = result.parameters
    rig = record.rig_parameters(
        L_m=p["L_m"].value,
        zeta=p["zeta"].value,
        g_m_s2=record.gravity_m_s2,
        mu0_s_per_m=p["mu0_s_per_m"].value,
        theta_b_rad=p["theta_b_rad"].value,
    ).with_stiffness(p["K_N_per_m1.5"].value)
    span = _fitted_span(t, result)
    model_t = t[span]
    fs = 1.0 / float(t[1] - t[0])
    run = simulate(
        Model(rig=rig, drive=Drive(), barrier=True),
        fitted["theta0_rad"],
        fitted["theta_dot0_rad_s"],
        settings=SimulationSettings(duration_s=model_t.size / fs, fs_hz=fs, poincare_phase=None),
    )
    theta = np.asarray(run.theta, dtype=float)[: model_t.size]
    return model_t[: theta.size], theta + fitted["offset_rad"]
