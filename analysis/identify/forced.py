"""Identification of a forced record on its own: L, zeta, K, mu0, the barrier position, the
sensor offset, and the table amplitude when no table channel measured it.

1. The drive from the record (:mod:`analysis.identify.drive`): frequency and phase from
   the tach, amplitude and phase from the table channel when there is one.
2. Start values by equation error in free flight (:mod:`analysis.identify.equation_error`),
   the barrier from where the swings stop, the contact law from the rig's nominal values
   (or the decays' identification, given as priors).
3. Multiple shooting (:mod:`analysis.identify.shooting`): first over short, unlinked
   segments spread over the record, where a few per cent of error in a start value still
   leaves each segment's response smooth in the parameters; then over the whole record in
   linked segments of a few drive periods.

The barrier position and the sensor zero are the parameters of the named causes
``barrier_offset`` and ``sensor_offset`` (docs/MODEL.md section 6), and an unmeasured table
amplitude is ``excitation_amplitude``'s: the fit switches those causes on, so the model is
built by the one mechanism every fit uses (:mod:`analysis.model_values`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from analysis import quantities as q
from analysis.dynamics.measured_regime import judge_record_regime
from analysis.dynamics.regime import Regime
from analysis.identify.drive import MeasuredDrive, measure_drive
from analysis.identify.equation_error import (
    FlightEstimate,
    TableMotion,
    barrier_level,
    flight_regression,
)
from analysis.identify.preprocess import (
    OUTLIER_SIGMA,
    RecordTails,
    find_bad_samples,
    noise_and_quantum,
    record_tails,
)
from analysis.identify.result import (
    Estimate,
    FitQuality,
    IdentificationError,
    IdentificationResult,
    SampledRecord,
)
from analysis.identify.shooting import (
    MAX_ITERATIONS,
    FreeParameter,
    Segments,
    ShootingFit,
    ShootingProblem,
    cut_segments,
)
from analysis.model import RigParameters
from analysis.model_values import (
    has_measurement,
    measured_angle,
    measurement_has_memory,
    packed_from_values,
)
from analysis.progress import ProgressText
from analysis.records import Record

SHORT_SEGMENT_S = 0.1  # first stage: short enough that 10 % off in omega is a small phase error
MAX_SHORT_SEGMENTS = 200
SEGMENT_S = 0.4  # second stage: a few drive periods at 10 Hz, about one swing at 2 Hz
# A chaotic record's response to a segment's state grows by e in a few tenths of a second,
# and a near-grazing impact makes it steep: its segments are shorter.
CHAOTIC_SEGMENT_S = 0.2
MIN_DURATION_S = 2.0
# a table amplitude no laser measured starts within this relative error of the stated one
# (eps = A / A_stated - 1): an amplifier a factor of 2 off is a broken rig, not a finding
PLAUSIBLE_EPS = (-0.5, 1.0)
SMOOTHING_S = 0.012


# Baseline parameters of a forced fit: name -> (finite-difference step, log scale, bounds)
BASELINE_PLANS: dict[str, tuple[float, bool, float, float]] = {
    q.omega_rad_s: (1e-7, True, 0.0, math.inf),
    q.zeta: (1e-6, False, 0.0, 0.5),
    q.K_N_per_m1_5: (1e-4, True, 1e-3, 1e14),
    q.mu0_s_per_m: (1e-4, False, 0.0, 50.0),
}


@dataclass(frozen=True)
class ForcedData(SampledRecord):
    """The fit's view of a forced record: times from 0, angle (NaN where excluded), the
    measured drive and the rig constants the lab knows (m, l, R, g), and its noise's tails
    (judged before any fit: heavy tails make every fit of it robust)."""

    t: np.ndarray
    y: np.ndarray
    valid: np.ndarray
    noise_rad: float
    rig: RigParameters
    drive: MeasuredDrive
    source: str = ""
    segment_s: float = SEGMENT_S  # linked segments over the whole record are this long
    tails: RecordTails | None = None

    @property
    def heavy_tailed(self) -> bool:
        """Whether the noise has heavy tails (fits then use a robust loss)."""
        return self.tails is not None and self.tails.heavy

    @property
    def tails_note(self) -> str:
        """What the heavy tails are and what the fits do about them (empty without)."""
        if not self.heavy_tailed:
            return ""
        tails = self.tails
        return (f"heavy-tailed noise: {tails.count} spikes of the angle's sample-to-sample "
                f"detail beyond {OUTLIER_SIGMA:g} sigma where Gaussian noise puts "
                f"{tails.expected:.2g}, of both signs, carrying {100 * tails.share:.2g} % of "
                "its squares; the fits use a robust (soft L1) loss")

    def for_regime(self, kind: str) -> ForcedData:
        """The same record fitted in segments suited to its regime (chaotic or undetermined
        records in CHAOTIC_SEGMENT_S)."""
        chaotic = kind in ("chaotic", "undetermined")
        return replace(self, segment_s=CHAOTIC_SEGMENT_S if chaotic else SEGMENT_S)


def forced_data(record: Record) -> ForcedData:
    """Bad samples out, noise from the data, the drive measured."""
    if not record.kind.driven:
        raise IdentificationError(f"{record.source or 'record'}: a {record.experiment} record, "
                                  "not a forced one")
    t = record.time_s - record.time_s[0]
    if t[-1] < MIN_DURATION_S:
        raise IdentificationError(
            f"{record.source or 'record'}: {t[-1]:.3g} s recorded; a forced record needs at "
            f"least {MIN_DURATION_S:g} s (tens of drive periods for a sound fit)"
        )
    valid, _, _ = find_bad_samples(record.angle_rad)
    y = np.where(valid, record.angle_rad, np.nan)
    noise, _ = noise_and_quantum(y)
    return ForcedData(t=t, y=y, valid=valid, noise_rad=float(noise),
                      rig=record.rig_parameters(), drive=measure_drive(record),
                      source=record.source, tails=record_tails(y))


@dataclass(frozen=True)
class ForcedModel:
    """How shared values become a model of a forced record: the causes switched on (their
    parameters join the values) and the drive phase (a value of its own when unknown)."""

    data: ForcedData
    causes: tuple[str, ...] = ()

    def packed(self, values: Mapping[str, float]) -> np.ndarray:
        """The packed vector for the integrator."""
        d = self.data
        phase = values.get(q.drive_phase_rad, d.drive.phase0_rad)
        drive = d.drive.model_drive(values.get(q.drive_frequency_hz))
        return packed_from_values(d.rig, drive, True, values, self.causes, phase)

    def measure(self, values: Mapping[str, float], t: np.ndarray, theta: np.ndarray,
                theta_dot0: float | None = None) -> np.ndarray:
        """The angle the sensor reports over a stretch of contiguous samples."""
        return measured_angle(self.causes, values, t, theta, theta_dot0)

    def problem(
        self, segments: Segments, free: Sequence[FreeParameter], fixed: Mapping[str, float],
        *, threads: int | None = None,
    ) -> ShootingProblem:
        """A multiple-shooting problem of this model on the record."""
        d = self.data
        return ShootingProblem(
            d.t, d.y, d.valid, d.noise_rad, segments, self.packed, list(free), fixed,
            measure=self.measure if has_measurement(self.causes) else None,
            measure_has_memory=measurement_has_memory(self.causes),
            rate_scale=d.drive.omega_rad_s, threads=threads, robust=d.heavy_tailed,
        )


def state_steps(data: ForcedData) -> tuple[float, float]:
    """Finite-difference steps of a segment's (theta, theta'), scaled to the swing."""
    amplitude = max(float(np.nanmax(data.y) - np.nanmin(data.y)), 1e-3)
    return 1e-6 * amplitude, 1e-6 * amplitude * data.drive.omega_rad_s


def smoothed_states(data: ForcedData, start: np.ndarray, offset: float) -> np.ndarray:
    """(theta, theta') at the given samples from a smoothed record (a start for the fit)."""
    window = max(5, round(SMOOTHING_S / data.dt) | 1)
    good = data.valid & np.isfinite(data.y)
    idx = np.arange(data.y.size)
    filled = np.interp(idx, idx[good], data.y[good])
    theta = savgol_filter(filled, window, 3)[start] - offset
    rate = savgol_filter(filled, window, 3, deriv=1, delta=data.dt)[start]
    return np.column_stack([theta, rate])


def impact_speed(data: ForcedData, level: float) -> float:
    """Typical speed [rad/s] at which the swings reach the barrier: the median, over the
    excursions that come within a fifth of their height of ``level``, of the fastest rise
    on the way up (gravity's torque vanishes at the bottom, so the swing arrives at its
    fastest)."""
    window = max(5, round(SMOOTHING_S / data.dt) | 1)
    good = data.valid & np.isfinite(data.y)
    idx = np.arange(data.y.size)
    filled = np.interp(idx, idx[good], data.y[good])
    ys = savgol_filter(filled, window, 3)
    rate = savgol_filter(filled, window, 3, deriv=1, delta=data.dt)
    centre = float(np.median(ys))
    near = ys > level - 0.2 * (level - centre)
    edges = np.flatnonzero(np.diff(near.astype(np.int8)) == 1) + 1  # arrivals near the barrier
    look = max(2, int(0.25 / (data.drive.frequency_hz * data.dt)))
    speeds = [rate[max(0, e - look):e + 1].max() for e in edges]
    speeds = [v for v in speeds if v > 0]
    return float(np.median(speeds)) if speeds else 0.0


def hertz_penetration_rad(rig: RigParameters, omega: float, K: float, speed: float) -> float:
    """Largest penetration of a Hertz impact at angular speed ``speed`` (docs/MODEL.md section 4
    oracle), as an angle."""
    L = rig.g_m_s2 / omega**2
    m_eff = rig.m_kg * L**2 / rig.l_m**2
    v = rig.l_m * speed
    return (5.0 * m_eff * v * v / (4.0 * K)) ** 0.4 / rig.l_m


def short_segments(data: ForcedData) -> Segments:
    """Unlinked short segments spread evenly over the record (stage 1)."""
    every = cut_segments(data.t, 0.0, SHORT_SEGMENT_S)
    take = np.unique(np.linspace(0, every.count - 1, min(every.count, MAX_SHORT_SEGMENTS))
                     .round().astype(np.int64))
    return Segments(every.start[take], every.fit_stop[take], every.fit_stop[take],
                    data.t[np.minimum(every.fit_stop[take], data.t.size - 1)],
                    np.zeros(take.size, dtype=bool))


def record_segments(data: ForcedData, length_s: float | None = None,
                    heldout_s: float = 0.0) -> Segments:
    """Linked segments over the whole record from its first sample, each ``length_s``
    (default: the record's ``segment_s``) fitted and then ``heldout_s`` forecast."""
    return cut_segments(data.t, 0.0, length_s or data.segment_s, heldout_s=heldout_s)


def inherited_states(new: Segments, old: Segments, old_states: np.ndarray,
                     fallback: np.ndarray) -> np.ndarray:
    """Start states of ``new``'s segments: the fitted state of an ``old`` segment that
    starts on the same sample, else ``fallback``'s row."""
    states = np.array(fallback, dtype=float, copy=True)
    pos = np.searchsorted(old.start, new.start)
    pos = np.minimum(pos, old.count - 1)
    same = old.start[pos] == new.start
    states[same] = old_states[pos[same]]
    return states


def fit_over_record(
    model: ForcedModel, free: Sequence[FreeParameter], fixed: Mapping[str, float], *,
    heldout_s: float = 0.0, threads: int | None = None, progress: ProgressText | None = None,
    start_from: tuple[ShootingFit, Segments] | None = None,
    max_iterations: int = MAX_ITERATIONS,
) -> tuple[ShootingFit, Segments]:
    """Multiple shooting over the whole record in linked segments of ``data.segment_s``,
    reached by halving: first segments half as long (states drawn onto the data from a
    smoother),
    then the full length from those fitted states.  A long segment's state must be close
    before the fit can improve it (near-grazing impacts make the response to it steep);
    half-length segments get there from a smoother's estimate.

    ``start_from``: an earlier fit whose segment starts include these (same layout or a
    finer one) gives the states, and no halving is needed."""
    say = progress or (lambda message: None)
    data = model.data
    offset = fixed.get(q.offset_rad, next((p.start for p in free if p.name == q.offset_rad),
                                          0.0))
    segments = record_segments(data, heldout_s=heldout_s)
    smooth = smoothed_states(data, segments.start, offset)
    if start_from is not None:
        states = inherited_states(segments, start_from[1], start_from[0].states, smooth)
        fit, _ = fit_model(model, segments, free, fixed, states, warm_states=False,
                           threads=threads, max_iterations=max_iterations)
        return fit, segments
    half = record_segments(data, 0.5 * data.segment_s)
    say(f"multiple shooting over the record in {half.count} linked segments")
    fit_half, _ = fit_model(model, half, free, fixed,
                            smoothed_states(data, half.start, offset), threads=threads,
                            max_iterations=max_iterations)
    say(f"  rms {fit_half.rms / data.noise_rad:.3g} x noise after {fit_half.iterations} "
        "iterations")
    values = fit_half.values
    free = [replace(p, start=values[p.name]) for p in free]
    states = inherited_states(segments, half, fit_half.states, smooth)
    say(f"multiple shooting over the record in {segments.count} linked segments")
    fit, _ = fit_model(model, segments, free, fixed, states, warm_states=False, threads=threads,
                       max_iterations=max_iterations)
    return fit, segments


def clock_parameter(frequency_hz: float) -> FreeParameter:
    """The drive frequency as a fitted parameter (records without tach or table channel)."""
    return FreeParameter(q.drive_frequency_hz, frequency_hz, 1e-8, True, 0.99 * frequency_hz,
                         1.01 * frequency_hz)


def free_parameters(
    names: Sequence[str], start: Mapping[str, float], extra: Sequence[FreeParameter] = ()
) -> list[FreeParameter]:
    """Free baseline parameters (steps and bounds of BASELINE_PLANS) plus ``extra``."""
    out = []
    for name in names:
        step, log, lo, hi = BASELINE_PLANS[name]
        out.append(FreeParameter(name, float(start[name]), step, log, lo, hi))
    return out + list(extra)


def fit_model(
    model: ForcedModel, segments: Segments, free: Sequence[FreeParameter],
    fixed: Mapping[str, float], states: np.ndarray, *, warm_states: bool = True,
    threads: int | None = None, max_iterations: int = MAX_ITERATIONS,
) -> tuple[ShootingFit, ShootingProblem]:
    """Fit: segment states alone first (when ``warm_states``), then everything."""
    problem = model.problem(segments, free, fixed, threads=threads)
    steps = state_steps(model.data)
    if warm_states:
        states = problem.fit_states(states, state_steps=steps)
    return problem.fit(states, state_steps=steps, max_iterations=max_iterations), problem


def _flight_at_stated_amplitude(
    data: ForcedData, motion: TableMotion, flight: FlightEstimate
) -> tuple[FlightEstimate, str | None]:
    """The flight regression again with the table amplitude held at the stated one, when
    the regression that fitted it (no laser watched the table) found one no rig has: on a
    record whose swing follows the drive, the table's terms and gravity's can trade off, and
    the regression then buys a smaller misfit with an absurd omega (19 times the true one
    on a 10 Hz period-2 record with dry friction).  Returns the estimate and a note, or the
    given estimate and None when its amplitude is plausible."""
    stated = data.drive.stated_amplitude_m
    if not stated or not stated > 0 or flight.amplitude_m is None:
        return flight, None
    eps = flight.amplitude_m / stated - 1.0
    if PLAUSIBLE_EPS[0] <= eps <= PLAUSIBLE_EPS[1]:
        return flight, None
    phase = motion.phase_rad if motion.phase_rad is not None else flight.phase_rad
    held = replace(motion, amplitude_m=stated, phase_rad=phase or 0.0)
    again = flight_regression(data.t, data.y, data.valid, data.noise_rad, held,
                              data.rig.g_m_s2)
    note = (f"the flight regression's table amplitude, {1e3 * flight.amplitude_m:.3g} mm "
            f"(omega {flight.omega_rad_s:.4g} rad/s), is no rig's against the stated "
            f"{1e3 * stated:.3g} mm: start values from a regression with the stated amplitude "
            f"(omega {again.omega_rad_s:.4g} rad/s)")
    return replace(again, amplitude_m=stated, phase_rad=held.phase_rad), note


@dataclass
class ForcedIdentification:
    """Everything the identification of a forced record found, for reports and as the start
    of the discrepancy analysis."""

    data: ForcedData
    flight: FlightEstimate
    model: ForcedModel
    fit: ShootingFit  # over the whole record (or the short segments' fit, see whole=False)
    segments: Segments
    short_fit: ShootingFit  # the first stage, over short unlinked segments
    short: Segments
    start: dict[str, float]  # where the first stage started (equation error, priors)
    notes: list[str] = field(default_factory=list)

    @property
    def values(self) -> dict[str, float]:
        """Every fitted value (baseline and the identification's own causes)."""
        return dict(self.fit.values)


def identify_forced(
    record: Record | ForcedData, *, priors: Mapping[str, float] | None = None,
    progress: ProgressText | None = None, threads: int | None = None, whole: bool = True,
) -> ForcedIdentification:
    """Identify a forced record on its own; ``priors`` (decays' values of omega, zeta, K,
    mu0) only replace the nominal start values.  ``whole=False`` stops after the short
    segments (the discrepancy analysis fits every model over the whole record itself)."""
    say = progress or (lambda message: None)
    data = record if isinstance(record, ForcedData) else forced_data(record)
    priors = dict(priors or {})
    notes = list(data.drive.notes)
    if data.heavy_tailed:
        notes.append(data.tails_note)
    drive = data.drive
    table = drive.table
    amplitude_known = table is not None
    motion = TableMotion(
        drive.omega_rad_s, drive.phase0_rad if drive.phase_known else None,
        table.amplitude_m.value if table is not None else None,
        table.h2.value if table is not None else 0.0,
        table.phi2_rad.value if table is not None else 0.0,
    )
    flight = flight_regression(data.t, data.y, data.valid, data.noise_rad, motion,
                               data.rig.g_m_s2)
    if not amplitude_known:
        flight, note = _flight_at_stated_amplitude(data, motion, flight)
        notes += [note] if note else []
    say(f"flight regression: omega {flight.omega_rad_s:.4g} rad/s, zeta {flight.zeta:.3g}, "
        f"sensor zero {flight.offset_rad:.3g} rad")
    rig = data.rig
    start = {
        q.omega_rad_s: priors.get(q.omega_rad_s, flight.omega_rad_s),
        q.zeta: priors.get(q.zeta, max(flight.zeta, 1e-3)),
        q.K_N_per_m1_5: priors.get(q.K_N_per_m1_5, rig.K_N_per_m1_5),
        q.mu0_s_per_m: priors.get(q.mu0_s_per_m, rig.mu0_s_per_m),
    }
    offset = flight.offset_rad
    level = barrier_level(data.y, data.valid)
    # the swings stop past the barrier by the contact's penetration (sampled maxima, and
    # the contact's damping, keep the measured stop a little short of the Hertz peak)
    penetration = hertz_penetration_rad(rig, start[q.omega_rad_s], start[q.K_N_per_m1_5],
                                        impact_speed(data, level))
    start[q.theta_b_rad] = level - offset - 0.8 * penetration
    start[q.offset_rad] = offset
    causes = ["barrier_offset", "sensor_offset"]
    extra = [
        FreeParameter(q.theta_b_rad, start[q.theta_b_rad], 1e-6, False, -0.5, 0.5),
        FreeParameter(q.offset_rad, offset, 1e-6, False, -1.0, 1.0),
    ]
    # a table amplitude no laser measured: the stated one times (1 + eps)
    if not amplitude_known:
        eps = (flight.amplitude_m / drive.stated_amplitude_m - 1.0) if flight.amplitude_m \
            else 0.0
        eps = float(np.clip(eps, *PLAUSIBLE_EPS))
        start[q.eps] = eps
        causes.append("excitation_amplitude")
        extra.append(FreeParameter(q.eps, eps, 1e-5, False, -0.9, 9.0))
    # The phase between drive and measured angle is fitted even when the tach or table
    # tell the drive's: a lagging sensor or a shifted tach shows as a phase offset, which
    # would otherwise bend every other parameter.  Its difference from the measured phase
    # is reported (and hints at a lag).
    phase = drive.phase0_rad if drive.phase_known else float(flight.phase_rad or 0.0)
    start[q.drive_phase_rad] = phase
    extra.append(FreeParameter(q.drive_phase_rad, phase, 1e-5, False, phase - math.pi,
                               phase + math.pi))
    if not drive.timing_known:
        # without the table channel the drive's frequency is the tach's (a few parts in 1e6
        # off) or the stated one (parts in 1e4): the fit refines it from the angle
        start[q.drive_frequency_hz] = drive.frequency_hz
        extra.append(clock_parameter(drive.frequency_hz))
    if not drive.phase_known:
        notes.append("drive frequency and phase fitted (neither tach nor table channel)")
    model = ForcedModel(data, tuple(causes))
    free = free_parameters(list(BASELINE_PLANS), start, extra)
    short = short_segments(data)
    say(f"multiple shooting over {short.count} short segments")
    fit1, _ = fit_model(model, short, free, {}, smoothed_states(data, short.start, offset),
                        threads=threads)
    values = fit1.values
    say(f"  rms {fit1.rms / data.noise_rad:.3g} x noise after {fit1.iterations} iterations: "
        + ", ".join(f"{k} {v:.4g}" for k, v in values.items()))
    if whole:
        fit2, segments = fit_over_record(
            model, [replace(p, start=values[p.name]) for p in free], {}, threads=threads,
            progress=say)
        say(f"  rms {fit2.rms / data.noise_rad:.3g} x noise after {fit2.iterations} iterations")
    else:
        fit2, segments = fit1, short
    return ForcedIdentification(data=data, flight=flight, model=model, fit=fit2,
                                segments=segments, short_fit=fit1, short=short,
                                start=dict(start), notes=notes)


def record_regime(record: Record, data: ForcedData) -> Regime:
    """The record's regime judged from its strobe points (on the tach, else on the measured
    drive), aware of its noise; 'undetermined', with the reason, when the record cannot be
    judged (too few drive periods, say)."""
    drive = data.drive
    try:
        regime, _ = judge_record_regime(
            np.asarray(record.angle_rad, dtype=float), record.sample_rate_hz, data.noise_rad,
            tach_indices=record.tach_indices if drive.clock is not None else None,
            frequency_hz=drive.frequency_hz, phase_rad=drive.phase0_rad,
        )
    except ValueError as error:
        return Regime("undetermined", None, f"undetermined: {error}")
    return regime


def fit_forced(
    record: Record, *, priors: Mapping[str, float] | None = None,
    progress: ProgressText | None = None,
) -> IdentificationResult:
    """``impact-rig identify`` of a forced record: every parameter it determines, with 95 %
    intervals, and the drive as measured."""
    data = forced_data(record)
    regime = record_regime(record, data)
    found = identify_forced(data.for_regime(regime.kind), priors=priors, progress=progress)
    result = identification_result(found, record.experiment)
    result.details["regime"] = regime.label
    return result


def identification_result(found: ForcedIdentification, experiment: str) -> IdentificationResult:
    """The report view of a forced identification (docs/MODEL.md section 7 keys)."""
    data = found.data
    fit = found.fit
    est = dict(fit.estimates)
    g = data.rig.g_m_s2
    parameters: dict[str, Estimate] = {}
    omega = est[q.omega_rad_s]
    ci = None
    if omega.ci95 is not None and omega.ci95[0] > 0:
        ci = (g / omega.ci95[1] ** 2, g / omega.ci95[0] ** 2)
    parameters[q.L_m] = Estimate(g / omega.value**2, ci)
    parameters[q.omega_rad_s] = omega
    for key in (q.zeta, q.K_N_per_m1_5, q.mu0_s_per_m, q.theta_b_rad, q.offset_rad):
        parameters[key] = est[key]
    K = est[q.K_N_per_m1_5]
    factor = 3.0 / (4.0 * math.sqrt(data.rig.R_m))
    parameters[q.E_Pa] = Estimate(K.value * factor, (K.ci95[0] * factor, K.ci95[1] * factor)
                                  if K.ci95 else None)
    parameters[q.R_m] = Estimate(data.rig.R_m)
    drive = data.drive
    if q.eps in est:
        e = est[q.eps]
        a = drive.stated_amplitude_m
        parameters[q.amplitude_m] = Estimate(a * (1 + e.value), (a * (1 + e.ci95[0]),
                                             a * (1 + e.ci95[1])) if e.ci95 else None)
    elif drive.table is not None:
        parameters[q.amplitude_m] = drive.table.amplitude_m
    if q.drive_phase_rad in est:
        parameters[q.drive_phase_rad] = est[q.drive_phase_rad]
    parameters[q.frequency_hz] = est.get(q.drive_frequency_hz, Estimate(drive.frequency_hz))
    quality = FitQuality(
        rms_residual_rad=fit.rms, noise_rad=data.noise_rad, n_samples=fit.n,
        n_excluded=int(data.valid.size - data.n_valid), variance_inflation=1.0,
        residual_lag1_correlation=_lag1(fit.residual),
    )
    warnings = []
    # on heavy-tailed noise the spikes alone lift the rms to several times the noise (2-4 x
    # on the reference records): the misfit is judged by the robust spread instead
    misfit, measure = fit.rms, "rms"
    if data.heavy_tailed:
        residual = fit.residual[np.isfinite(fit.residual)]
        misfit, measure = 1.4826 * float(np.median(np.abs(residual))), "robust spread"
    if misfit > 3.0 * data.noise_rad:
        warnings.append(
            f"poor fit: residual {measure} {misfit:.3g} rad is {misfit / data.noise_rad:.3g} x "
            "the sample noise; the model misses something (see impact-rig analyze)"
        )
    details: dict[str, Any] = {
        "drive": drive.as_json(),
        "segments": found.segments.count,
        "segment_s": float(data.t[found.segments.fit_stop[0]] - data.t[found.segments.start[0]]),
        "continuity_rms": np.sqrt(np.mean(fit.jumps**2, axis=0)).tolist()
        if fit.jumps.size else [],
        "flight_regression": {q.omega_rad_s: found.flight.omega_rad_s, q.zeta: found.flight.zeta,
                              q.offset_rad: found.flight.offset_rad,
                              q.amplitude_m: found.flight.amplitude_m},
        "iterations": fit.iterations,
        "solver": fit.message,
    }
    return IdentificationResult(
        experiment=experiment,
        method="forced: equation error start, multiple shooting over the record",
        parameters=parameters, quality=quality, warnings=tuple(found.notes + warnings),
        details=details,
    )


def _lag1(residual: np.ndarray) -> float:
    r = residual[np.isfinite(residual)]
    if r.size < 3:
        return 0.0
    return float(np.corrcoef(r[:-1], r[1:])[0, 1])
