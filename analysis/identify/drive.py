"""The drive of a forced record, measured: frequency and phase from the tach, amplitude, phase
and second harmonic from the table channel (the laser), compared with the stated drive.

docs/MODEL.md section 6: the tach pulse marks drive phase 0, x_t = A sin(Omega t) there; the
drive clock fitted to the pulses (:func:`analysis.dynamics.strobe.clock_from_tach`) gives
the frequency and the phase, to far better than a sample.

The table is fitted as x_t = A sin(Omega t + phase) + A h2 sin(2 (Omega t + phase) +
phi2) + c at the measured frequency.  The model's drive phase comes from the table when
there is one (it is the motion that drives the pendulum), else from the tach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from analysis import quantities as q
from analysis.dynamics.strobe import StrobeClock, clock_from_tach
from analysis.identify.intervals import Z95, sandwich_covariance
from analysis.identify.result import Estimate, FitQuality, IdentificationError, IdentificationResult
from analysis.model import Drive
from analysis.records import Record

PHASE_DISAGREEMENT_RAD = 0.1
AMPLITUDE_DISAGREEMENT = 0.02


@dataclass(frozen=True)
class TableFit:
    """The table channel's motion: A sin(Omega t + phase) + A h2 sin(2 (Omega t + phase) +
    phi2) + centre, with 95 % intervals."""

    amplitude_m: Estimate
    phase_rad: Estimate
    h2: Estimate
    phi2_rad: Estimate
    rms_residual_m: float
    noise_m: float
    n_samples: int
    n_excluded: int
    variance_inflation: float
    lag1_correlation: float


def _harmonic_basis(t: np.ndarray, omega: float) -> np.ndarray:
    return np.column_stack([np.sin(omega * t), np.cos(omega * t), np.sin(2 * omega * t),
                            np.cos(2 * omega * t), np.ones_like(t)])


def fit_table(t: np.ndarray, x: np.ndarray, omega: float) -> TableFit:
    """Least-squares fit of the fundamental and second harmonic at angular frequency omega."""
    good = np.isfinite(x)
    t, x = t[good], x[good]
    basis = _harmonic_basis(t, omega)
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    residual = basis @ coef - x
    cov = sandwich_covariance([(residual, basis)]).matrix
    s1, c1, s2, c2 = coef[:4]
    a1 = math.hypot(s1, c1)
    phase = math.atan2(c1, s1)
    a2 = math.hypot(s2, c2)
    # x2 = a2 sin(2 Omega t + psi2) = a2 sin(2 (Omega t + phase) + phi2): phi2 = psi2 - 2 phase
    psi2 = math.atan2(c2, s2)
    phi2 = float(np.angle(np.exp(1j * (psi2 - 2.0 * phase))))

    def interval(value: float, gradient: np.ndarray) -> Estimate:
        half = Z95 * math.sqrt(max(float(gradient @ cov @ gradient), 0.0))
        return Estimate(value, (value - half, value + half))

    g_a1 = np.array([s1 / a1, c1 / a1, 0, 0, 0])
    g_ph = np.array([-c1 / a1**2, s1 / a1**2, 0, 0, 0])
    g_a2 = np.array([0, 0, s2, c2, 0]) / max(a2, 1e-300)
    g_h2 = g_a2 / a1 - a2 / a1**2 * g_a1
    g_psi2 = np.array([0, 0, -c2, s2, 0]) / max(a2, 1e-300) ** 2
    noise = float(np.std(np.diff(x, 2)) / math.sqrt(6.0)) if x.size > 3 else math.nan
    inflation = sandwich_covariance([(residual, basis)]).variance_inflation
    rho1 = float(np.corrcoef(residual[:-1], residual[1:])[0, 1]) if residual.size > 3 else 0.0
    return TableFit(
        amplitude_m=interval(a1, g_a1), phase_rad=interval(phase, g_ph),
        h2=interval(a2 / a1, g_h2), phi2_rad=interval(phi2, g_psi2 - 2.0 * g_ph),
        rms_residual_m=float(np.sqrt(np.mean(residual**2))), noise_m=noise,
        n_samples=int(t.size), n_excluded=int(np.count_nonzero(~good)),
        variance_inflation=inflation, lag1_correlation=rho1,
    )


@dataclass(frozen=True)
class MeasuredDrive:
    """The drive of a forced record as measured, and as stated in its metadata."""

    stated_frequency_hz: float
    stated_amplitude_m: float
    frequency_hz: float
    phase0_rad: float  # drive phase at the record's first sample
    frequency_source: str  # "tach", "table" or "stated"
    phase_source: str  # "table", "tach" or "unknown"
    clock: StrobeClock | None = None
    table: TableFit | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def omega_rad_s(self) -> float:
        """Measured drive angular frequency."""
        return 2.0 * math.pi * self.frequency_hz

    @property
    def phase_known(self) -> bool:
        """False when neither tach nor table tells the phase (the fit must find it)."""
        return self.phase_source != "unknown"

    @property
    def timing_known(self) -> bool:
        """True when the table channel times the drive: its thousands of samples place the
        phase and frequency far better than the angle's fit needs.  A tach alone does not:
        pulses quantised to a sample leave the frequency a few parts in 1e6 off and the
        phase a milliradian or so, which over a minute at 10 Hz moves the response by more
        than a quiet sensor's noise, so the fits refine both from the angle itself."""
        return self.table is not None

    def measured_sizes(self) -> dict[str, Estimate]:
        """What the table channel measured of the drive causes' sizes: the amplitude's
        error against the stated one (``eps``) and the second harmonic (``h2``), with 95 %
        intervals; empty without a table channel."""
        if self.table is None:
            return {}
        a, stated = self.table.amplitude_m, self.stated_amplitude_m
        ci = None if a.ci95 is None else (a.ci95[0] / stated - 1.0, a.ci95[1] / stated - 1.0)
        return {q.eps: Estimate(a.value / stated - 1.0, ci), q.h2: self.table.h2}

    def model_drive(self, frequency_hz: float | None = None) -> Drive:
        """The baseline model's drive: the stated amplitude, a pure sine, at the measured
        frequency (or the one given; its phase goes into the packed vector as PHASE0)."""
        return Drive(amplitude_m=self.stated_amplitude_m,
                     frequency_hz=self.frequency_hz if frequency_hz is None else frequency_hz)

    def as_json(self) -> dict[str, Any]:
        """The measured drive against the stated one, for reports."""
        out: dict[str, Any] = {
            "stated": {q.frequency_hz: self.stated_frequency_hz,
                       q.amplitude_m: self.stated_amplitude_m},
            q.frequency_hz: self.frequency_hz,
            "frequency_source": self.frequency_source,
            "frequency_offset_ppm": 1e6 * (self.frequency_hz / self.stated_frequency_hz - 1.0),
            "phase0_rad": self.phase0_rad,
            "phase_source": self.phase_source,
            "notes": list(self.notes),
        }
        if self.clock is not None:
            out["tach"] = self.clock.summary()
        if self.table is not None:
            tf = self.table
            out["table"] = {
                q.amplitude_m: tf.amplitude_m.as_json(), "phase_rad": tf.phase_rad.as_json(),
                q.h2: tf.h2.as_json(), q.phi2_rad: tf.phi2_rad.as_json(),
                "amplitude_vs_stated": tf.amplitude_m.value / self.stated_amplitude_m - 1.0,
                "rms_residual_m": tf.rms_residual_m,
            }
        return out


def _stated(record: Record) -> tuple[float, float]:
    drive = record.drive or {}
    f = drive.get(q.frequency_hz)
    a = drive.get(q.amplitude_m)
    if not f or not (float(f) > 0):
        raise IdentificationError(
            f"{record.source or 'record'}: a forced record needs drive.frequency_hz > 0 in its "
            "metadata (docs/MODEL.md section 5)"
        )
    if not a or not (float(a) > 0):
        raise IdentificationError(
            f"{record.source or 'record'}: a forced record needs drive.amplitude_m > 0 in its "
            "metadata (docs/MODEL.md section 5)"
        )
    return float(f), float(a)


def _has_table(record: Record) -> bool:
    return record.table_m is not None and np.count_nonzero(np.isfinite(record.table_m)) > 16


def measure_drive(record: Record) -> MeasuredDrive:
    """Frequency and phase from the tach (else the table, else the stated frequency with
    an unknown phase), amplitude and harmonic content from the table when there is one."""
    f_stated, a_stated = _stated(record)
    t = record.time_s - record.time_s[0]
    notes: list[str] = []
    clock = None
    if record.tach_indices.size >= 3:
        try:
            clock = clock_from_tach(record.tach_indices, record.sample_rate_hz,
                                    stated_frequency_hz=f_stated)
        except ValueError as error:
            notes.append(f"tach not used: {error}")
    if clock is not None:
        frequency, source = clock.frequency_hz, "tach"
        if clock.extra_pulses or clock.missing_pulses:
            notes.append(f"tach: {clock.extra_pulses} pulse(s) off the drive clock ignored, "
                         f"{clock.missing_pulses} period(s) without a pulse")
    else:
        frequency, source = f_stated, "stated"
    table = None
    phase, phase_source = 0.0, "unknown"
    if _has_table(record):
        # the table's samples time the drive better than the tach's pulses (see timing_known)
        omega = _refine_frequency(t, np.asarray(record.table_m, dtype=float),
                                  2.0 * math.pi * frequency,
                                  span=2e-4 if clock is not None else 2e-2)
        frequency, source = omega / (2.0 * math.pi), "table"
        table = fit_table(t, np.asarray(record.table_m, dtype=float), omega)
        phase, phase_source = table.phase_rad.value, "table"
        eps = table.amplitude_m.value / a_stated - 1.0
        if abs(eps) > AMPLITUDE_DISAGREEMENT:
            notes.append(f"the table moves {table.amplitude_m.value * 1e3:.4g} mm, "
                         f"{100 * eps:+.3g} % off the stated {a_stated * 1e3:.4g} mm")
        if clock is not None:
            gap = float(np.angle(np.exp(1j * (table.phase_rad.value
                                              - clock.phase_at_start_rad))))
            if abs(gap) > PHASE_DISAGREEMENT_RAD:
                notes.append(f"the table's phase at the tach pulses is {gap:.3g} rad, not 0: "
                             "the model follows the table")
    elif clock is not None:
        phase, phase_source = clock.phase_at_start_rad, "tach"
        notes.append("no table channel: drive phase from the tach, amplitude as stated")
    else:
        notes.append("neither table channel nor tach: drive frequency as stated, phase fitted")
    if source != "stated":
        ppm = 1e6 * (frequency / f_stated - 1.0)
        if abs(ppm) > 1e3:
            notes.append(f"the drive runs at {frequency:.6g} Hz, {ppm:+.3g} ppm off the stated "
                         f"{f_stated:.6g} Hz")
    return MeasuredDrive(
        stated_frequency_hz=f_stated, stated_amplitude_m=a_stated, frequency_hz=frequency,
        phase0_rad=phase, frequency_source=source, phase_source=phase_source, clock=clock,
        table=table, notes=tuple(notes),
    )


def _refine_frequency(t: np.ndarray, x: np.ndarray, omega: float, span: float = 2e-2) -> float:
    """The angular frequency within ``span`` (relative) of ``omega`` that best fits the table
    channel."""
    good = np.isfinite(x)
    tt, xx = t[good], x[good]

    def misfit(w: float) -> float:
        basis = _harmonic_basis(tt, w)
        coef, *_ = np.linalg.lstsq(basis, xx, rcond=None)
        return float(np.sum((basis @ coef - xx) ** 2))

    found = minimize_scalar(misfit, bounds=((1 - span) * omega, (1 + span) * omega),
                            method="bounded", options={"xatol": 1e-10 * omega})
    return float(found.x)


def fit_drive(record: Record, *, estimate_frequency: bool = False) -> IdentificationResult:
    """Drive amplitude (m), phase (rad), frequency (Hz) and second harmonic from the table
    channel, as an identification result (``impact-rig identify`` of the table alone)."""
    if record.table_m is None:
        raise IdentificationError(
            f"{record.source or 'record'}: no table_m column; a forced record without the "
            "table channel relies on its stated drive and has nothing to fit"
        )
    stated = (record.drive or {}).get(q.frequency_hz)
    if not stated:
        raise IdentificationError("a forced record needs drive.frequency_hz in its metadata")
    t = record.time_s - record.time_s[0]
    x = np.asarray(record.table_m, dtype=float)
    if np.count_nonzero(np.isfinite(x)) < 16:
        raise IdentificationError(f"too few table samples: {np.count_nonzero(np.isfinite(x))}")
    omega = 2.0 * math.pi * float(stated)
    if omega * (t[-1] - t[0]) < 4.0 * math.pi:
        raise IdentificationError("record too short: fewer than 2 drive periods")
    if estimate_frequency:
        omega = _refine_frequency(t, x, omega)
    table = fit_table(t, x, omega)
    parameters = {
        q.amplitude_m: table.amplitude_m,
        "phase_rad": table.phase_rad,
        q.frequency_hz: Estimate(omega / (2.0 * math.pi)),
        q.h2: table.h2,
        q.phi2_rad: table.phi2_rad,
    }
    quality = FitQuality(
        rms_residual_rad=table.rms_residual_m, noise_rad=table.noise_m,
        n_samples=table.n_samples, n_excluded=table.n_excluded,
        variance_inflation=table.variance_inflation,
        residual_lag1_correlation=table.lag1_correlation, unit="m",
    )
    warnings = []
    stated_amp = (record.drive or {}).get(q.amplitude_m)
    if stated_amp:
        eps = table.amplitude_m.value / float(stated_amp) - 1.0
        if abs(eps) > AMPLITUDE_DISAGREEMENT:
            warnings.append(
                f"table amplitude {table.amplitude_m.value:.4g} m differs from the stated "
                f"{stated_amp:.4g} m by {100 * eps:.2g} %"
            )
    details: dict[str, Any] = {"units_of_residual": "m (table displacement)",
                               "stated_frequency_hz": float(stated)}
    tach = record.tach_indices[record.tach_indices < record.time_s.size]
    if tach.size:
        # docs/MODEL.md: the tach pulse marks drive phase 0, so the table's phase there should be 0.
        at_tach = np.angle(np.exp(1j * (omega * (record.time_s[tach] - record.time_s[0])
                                        + table.phase_rad.value)))
        details["table_phase_at_tach_rad"] = float(np.angle(np.mean(np.exp(1j * at_tach))))
        if abs(details["table_phase_at_tach_rad"]) > PHASE_DISAGREEMENT_RAD:
            warnings.append(
                f"the table is at phase {details['table_phase_at_tach_rad']:.3g} rad at the tach "
                "pulses, not 0: tach and table channel disagree on the drive phase"
            )
    return IdentificationResult(
        experiment=record.experiment, method="forced: sine fit of the table channel",
        parameters=parameters, quality=quality, warnings=tuple(warnings), details=details,
    )
