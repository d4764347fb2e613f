"""Forced records: drive amplitude and phase from the table channel; the model is held from decays.

The table displacement is fitted as x_t = A sin(Omega t + phase) + c by linear least
squares at the stated drive frequency (or, when asked, with the frequency refined
by a one-dimensional search).  MODEL.md places drive phase 0 at the tach pulse, so
the phase here is the one to compare with the tach marks.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from analysis.identify.intervals import Z95, sandwich_covariance
from analysis.identify.result import Estimate, FitQuality, IdentificationError, IdentificationResult
from analysis.records import Record


def _sine_fit(t: np.ndarray, x: np.ndarray, omega: float) -> tuple[np.ndarray, np.ndarray]:
    basis = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return coef, basis


def fit_drive(record: Record, *, estimate_frequency: bool = False) -> IdentificationResult:
    """Drive amplitude (m), phase (rad) and frequency (Hz) from the table channel."""
    if record.table_m is None:
        raise IdentificationError(
            f"{record.source or 'record'}: no table_m column; a forced record without the "
            "table channel relies on its stated drive and has nothing to fit"
        )
    stated = (record.drive or {}).get("frequency_hz")
    if not stated:
        raise IdentificationError("a forced record needs drive.frequency_hz in its metadata")
    good = np.isfinite(record.table_m)
    t = record.time_s[good] - record.time_s[0]
    x = record.table_m[good]
    if t.size < 16:
        raise IdentificationError(f"too few table samples: {t.size}")
    omega = 2.0 * math.pi * float(stated)
    if omega * (t[-1] - t[0]) < 4.0 * math.pi:
        raise IdentificationError("record too short: fewer than 2 drive periods")
    if estimate_frequency:
        found = minimize_scalar(
            lambda w: float(np.sum((_sine_fit(t, x, w)[1] @ _sine_fit(t, x, w)[0] - x) ** 2)),
            bounds=(0.98 * omega, 1.02 * omega), method="bounded",
            options={"xatol": 1e-9 * omega},
        )
        omega = float(found.x)
    coef, basis = _sine_fit(t, x, omega)
    residual = basis @ coef - x
    cov = sandwich_covariance([(residual, basis)])
    s, c = coef[0], coef[1]
    amplitude = math.hypot(s, c)
    phase = math.atan2(c, s)
    grad_a = np.array([s / amplitude, c / amplitude, 0.0])
    grad_p = np.array([-c / amplitude**2, s / amplitude**2, 0.0])
    half_a = Z95 * math.sqrt(grad_a @ cov.matrix @ grad_a)
    half_p = Z95 * math.sqrt(grad_p @ cov.matrix @ grad_p)
    parameters = {
        "amplitude_m": Estimate(amplitude, (amplitude - half_a, amplitude + half_a)),
        "phase_rad": Estimate(phase, (phase - half_p, phase + half_p)),
        "frequency_hz": Estimate(omega / (2.0 * math.pi)),
    }
    noise = float(np.std(np.diff(x, 2)) / math.sqrt(6.0))
    quality = FitQuality(
        rms_residual_rad=float(np.sqrt(np.mean(residual**2))), noise_rad=noise,
        n_samples=int(t.size), n_excluded=int(np.count_nonzero(~good)),
        variance_inflation=cov.variance_inflation,
        residual_lag1_correlation=cov.lag1_correlation, unit="m",
    )
    warnings = []
    stated_amp = (record.drive or {}).get("amplitude_m")
    if stated_amp:
        eps = amplitude / float(stated_amp) - 1.0
        if abs(eps) > 0.02:
            warnings.append(
                f"table amplitude {amplitude:.4g} m differs from the stated {stated_amp:.4g} m "
                f"by {100 * eps:.2g} %"
            )
    details = {"units_of_residual": "m (table displacement)", "stated_frequency_hz": float(stated)}
    tach = record.tach_indices[record.tach_indices < record.time_s.size]
    if tach.size:
        # MODEL.md: the tach pulse marks drive phase 0, so the table's phase there should be 0.
        at_tach = np.angle(np.exp(1j * (omega * (record.time_s[tach] - record.time_s[0]) + phase)))
        details["table_phase_at_tach_rad"] = float(np.angle(np.mean(np.exp(1j * at_tach))))
        if abs(details["table_phase_at_tach_rad"]) > 0.1:
            warnings.append(
                f"the table is at phase {details['table_phase_at_tach_rad']:.3g} rad at the tach "
                "pulses, not 0: tach and table channel disagree on the drive phase"
            )
    return IdentificationResult(
        experiment=record.experiment, method="forced: sine fit of the table channel",
        parameters=parameters, quality=quality, warnings=tuple(warnings),
        details=details,
    )
