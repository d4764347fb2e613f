"""What a fit's residual still holds: whether it is white noise at the record's own level,
and the structure that says what the model misses (docs/MODEL.md section 6,
``unexplained`` and ``residual_findings``).

:func:`read_residual` judges the residual (``model - data``, NaN or not ``valid`` where
not fitted) and names what it finds in it: a spectral ``line`` off the drive's harmonics,
a ``trend`` of offset or gain over the record, heavy-tailed noise (``outliers``).  The
other findings need more than the residual: :func:`drive_frequency_finding` (the tach's
clock against the stated frequency), :func:`timing_finding` (the table channel's phase at
the tach pulses) and :func:`backbone_finding` (a decay's frequency against its swing,
the record's and the model's curve's).

Every check controls its false alarms the same way: on a residual of white noise a
finding shows with a chance of at most FALSE_ALARM, whatever the record's length; and
it must also be big enough to matter (MIN_STRUCTURE of the noise's rms), because at
60 000 samples a significance test alone flags structure far too small to change any
fit.  The numbers behind each threshold are in the constants' comments.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
from scipy import fft as sp_fft
from scipy import stats

from analysis import quantities as q
from analysis.dynamics.lines import FALSE_ALARM, find_lines, periodogram
from analysis.dynamics.strobe import StrobeClock
from analysis.identify.drive import fit_table
from analysis.identify.intervals import Z95, sandwich_covariance
from analysis.identify.preprocess import (
    GAUSSIAN_BEYOND,
    OUTLIER_SIGMA,
    noise_and_quantum,
    tail_spikes,
)

KINDS = ("line", "drive_frequency", "trend", "timing", "outliers", "backbone",
         "constancy", "implausible_gain")

Z_FINDING = float(stats.norm.isf(FALSE_ALARM / 2.0))  # two-sided: 3.89
# Structure counts when its rms reaches this fraction of the noise's.  It then adds 2 %
# to the residual's rms; a fit's own imperfections (parameters off by their standard
# error, quantisation, integrator tolerance) leave far less, and at 60 000 samples the
# residual's structured power is measured to about 0.013 of the noise power (its
# standard error, ``excess_se`` in read_residual), so 0.2^2 = 0.04 stands 3 of them clear.
MIN_STRUCTURE = 0.2
# The residual's sample-to-sample scatter (the robust estimator the record's noise comes
# from) may exceed the record's noise by this factor before the residual counts as
# carrying broadband structure.  The two estimates of the same noise agree to ~10 %,
# except on a converter whose step is about the noise's size: there the record's (a
# median of whole steps) reads up to 31 % low at 0.8-0.9 steps of noise (1500 draws), and
# the caller's estimate may be 10 % off besides.  A white residual at 4.9 x the noise,
# which the fixed ratio this replaces let through, stands far above it.
SCATTER_LIMIT = 1.75
LJUNG_BOX_LAGS = 20
MAX_LINES = 5
# lines fitted to find the MAX_LINES largest: a few times more, as a few may prove too small
# (a residual far from white shows hundreds, and fitting them all costs seconds)
MAX_FITTED_LINES = 4 * MAX_LINES
PHASE_HARMONICS = 8  # spikes locked to any of these harmonics of the drive are a misfit
# Backbone: a mismatch of the frequency's change across the swing's amplitudes this large
# (a pendulum's own backbone, A^2 / 16, moves it 0.1 % at 0.13 rad) is worth naming.
BACKBONE_MIN = 1e-3
BACKBONE_PERIODS = 9  # whole periods a slope of frequency against amplitude needs
# Periods whose swing is below this fraction of the largest are left out: A^2 there holds
# 1 % of the backbone's lever, while what else times a crossing grows as the swing dies (a
# Coulomb model's alternating centre, a sensor zero: z fell from 14 to 3.7 on a hairspring
# decay read against a fitted friction model).
BACKBONE_SMALLEST = 0.1
# Drive clocks: the generator's and the data logger's quartz each hold tens of ppm.
DRIVE_TOLERANCE_PPM = 100.0
# A tach pulse is marked on the first sample at or after it and taken half a sample
# earlier, so each mark is off by at most half a sample (not a random error when the
# period is a whole number of samples: every pulse is off alike).
PULSE_MARK_ERROR_SAMPLES = 0.5


def rules_json() -> dict[str, dict[str, Any]]:
    """The reading's fixed rules, each as ``{"value", "why"}`` (a report's ``policy``)."""
    return {
        "false_alarm": {"value": FALSE_ALARM, "why": "chance that a check finds structure "
                        "in white noise, whatever the record's length"},
        "min_structure": {"value": MIN_STRUCTURE, "why": "structure counts from this "
                          "fraction of the noise's rms (smaller changes no fit)"},
        "scatter_limit": {"value": SCATTER_LIMIT, "why": "the residual's sample-to-sample "
                          "scatter may exceed the record's noise by this factor"},
        "ljung_box_lags": {"value": LJUNG_BOX_LAGS, "why": "lags of the whiteness test"},
        "backbone_min": {"value": BACKBONE_MIN, "why": "a decay's frequency change across "
                         "its swing that differs from the model's by this much is named"},
    }


@dataclass(frozen=True)
class Finding:
    """One thing the residual (or the drive channels) shows: a kind from KINDS, a sentence
    with the numbers for a reader, and the numbers themselves (SI units in their names)."""

    kind: str
    sentence: str
    numbers: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"finding kind {self.kind!r}: not one of {', '.join(KINDS)}")

    def as_json(self) -> dict[str, Any]:
        """``{"kind", "text", **numbers}``, an entry of the report's ``residual_findings``."""
        return {"kind": self.kind, "text": self.sentence, **self.numbers}


@dataclass(frozen=True)
class ResidualReading:
    """Whether a residual is white noise at the record's level, and what structure it holds.

    ``structured`` is the verdict (``unexplained`` in the report), ``why`` one sentence
    that completes "the model still misses something: ..." (or says the residual is
    noise).  ``floor_rad`` is the white level measured from the residual's upper half
    band, ``structured_rms_rad`` the rms of what lies above it (``excess_z`` standard
    errors from none), ``scatter_ratio`` the residual's sample-to-sample scatter over
    the record's noise ``noise_rad``.
    """

    structured: bool
    why: str
    noise_rad: float
    rms_rad: float
    floor_rad: float
    structured_rms_rad: float
    excess_z: float
    ljung_box_q: float
    ljung_box_lags: int
    ljung_box_p: float
    scatter_ratio: float
    n_samples: int
    findings: tuple[Finding, ...] = ()

    def as_json(self) -> dict[str, Any]:
        """The verdict, its statistics and the findings as plain values."""
        return {
            "structured": self.structured, "why": self.why, "noise_rad": self.noise_rad,
            "rms_rad": self.rms_rad, "floor_rad": self.floor_rad,
            "structured_rms_rad": self.structured_rms_rad, "excess_z": self.excess_z,
            "ljung_box_q": self.ljung_box_q, "ljung_box_lags": self.ljung_box_lags,
            "ljung_box_p": self.ljung_box_p, "scatter_ratio": self.scatter_ratio,
            "n_samples": self.n_samples,
            "findings": [f.as_json() for f in self.findings],
        }


def read_residual(
    t_s: np.ndarray, residual_rad: np.ndarray, valid: np.ndarray | None, noise_rad: float, *,
    drive_frequency_hz: float | None = None, subharmonic: int = 1,
    model_rad: np.ndarray | None = None, backbone: bool = False,
    beside: Sequence[Finding] = (),
) -> ResidualReading:
    """Judge a residual (``model - data`` on uniform times ``t_s``) against white noise.

    ``noise_rad`` is the record's white-noise level (from the raw angle, good to ~10 %).
    ``drive_frequency_hz`` (with ``subharmonic`` n for a period-n response) names the
    frequencies whose harmonics are the drive's and never reported as lines;
    ``model_rad`` (the fitted curve) lets the trend tell a gain drift from an offset one,
    and with ``backbone`` (a decay's record) compares the record's backbone with the
    model's (:func:`backbone_finding`).  ``beside`` are findings made outside the residual
    (a decay's parameters refitted on its parts: :mod:`analysis.discrepancy.constancy`).

    The verdict: structure remains when the residual is not white (a Ljung-Box test over
    LJUNG_BOX_LAGS lags of valid pairs, p < FALSE_ALARM) and the power above its own
    white floor is significant and at least MIN_STRUCTURE^2 of it; or when its
    sample-to-sample scatter exceeds the record's noise by SCATTER_LIMIT (broadband
    structure, which no floor measured from the residual itself can show); or when a
    line, a trend, a backbone or a finding ``beside`` of kind ``constancy`` or
    ``implausible_gain`` is found (each as significant, and as big, on its own).
    """
    t, r, ok = _checked(t_s, residual_rad, valid)
    if backbone and model_rad is None:
        raise ValueError("backbone=True needs model_rad, the fitted curve")
    if not (math.isfinite(noise_rad) and noise_rad > 0):
        raise ValueError(f"noise_rad = {noise_rad!r}: must be a positive number")
    if drive_frequency_hz is not None and not drive_frequency_hz > 0:
        raise ValueError(f"drive_frequency_hz = {drive_frequency_hz!r}: must be positive")
    if subharmonic < 1:
        raise ValueError(f"subharmonic = {subharmonic}: must be 1 or more")
    values = r[ok]
    n = values.size
    mean_square = float(np.mean(values**2))
    centred = np.where(ok, r - values.mean(), 0.0)
    # the white floor from the plain periodogram, which weighs every sample alike as the
    # mean square does (a window would weigh a spike by where it falls)
    upper = periodogram(centred, ok, window=False)[r.size // 4:]
    floor_power = float(np.median(upper)) / math.log(2.0)
    floor = math.sqrt(floor_power)
    excess = mean_square / floor_power - 1.0
    # standard error of the excess for white noise: the mean square's (2/n) and that of
    # the median of the upper half's independent bins (2.08 / their number)
    excess_se = math.sqrt(2.0 / n + 2.08 / upper.size)
    structured_rms = floor * math.sqrt(max(excess, 0.0))
    q_stat, p = _ljung_box(r, ok, LJUNG_BOX_LAGS)
    scatter = noise_and_quantum(values)[0] / noise_rad
    findings: list[Finding] = []
    base = None if drive_frequency_hz is None else drive_frequency_hz / subharmonic
    findings += _lines(t, r, ok, floor, base, drive_frequency_hz)
    findings += _trends(t, r, ok, floor, model_rad)
    if backbone:
        model = np.asarray(model_rad, dtype=float)
        found = backbone_finding(t, model - np.where(ok, r, 0.0), model, ok, noise_rad)
        findings += [found] if found is not None else []
    outliers = _outliers(t, r, ok, base)
    if outliers is not None:
        findings.append(outliers)
    findings += beside
    nonwhite = p < FALSE_ALARM and excess > Z_FINDING * excess_se \
        and structured_rms >= MIN_STRUCTURE * floor
    broadband = scatter > SCATTER_LIMIT
    # each as significant and big
    named = any(f.kind in ("line", "trend", "backbone", "constancy", "implausible_gain")
                for f in findings)
    structured = nonwhite or broadband or named
    why = _why(structured, nonwhite, broadband, structured_rms, floor, noise_rad, p, scatter,
               findings, math.sqrt(mean_square))
    return ResidualReading(
        structured=structured, why=why, noise_rad=float(noise_rad),
        rms_rad=math.sqrt(mean_square), floor_rad=floor, structured_rms_rad=structured_rms,
        excess_z=excess / excess_se, ljung_box_q=q_stat, ljung_box_lags=LJUNG_BOX_LAGS,
        ljung_box_p=p, scatter_ratio=scatter, n_samples=n, findings=tuple(findings),
    )


def drive_frequency_finding(
    clock: StrobeClock, stated_frequency_hz: float, *,
    tolerance_ppm: float = DRIVE_TOLERANCE_PPM,
) -> Finding | None:
    """The tach's drive frequency against the stated one, when they disagree beyond what
    the clocks and the pulses' sampling allow.

    ``clock`` is the line fitted through the tach pulses
    (:func:`analysis.dynamics.strobe.clock_from_tach`, or ``MeasuredDrive.clock``).  The
    allowance is Z_FINDING standard errors of the fitted frequency, plus the most a
    half-sample error in every pulse mark can tilt the least-squares line (3 x 0.5
    samples over the pulses' span), plus ``tolerance_ppm`` for two quartz clocks.
    """
    if clock.source != "tach":
        raise ValueError(f"a {clock.source!r} clock: the drive frequency is measured by a tach")
    if not stated_frequency_hz > 0:
        raise ValueError(f"stated_frequency_hz = {stated_frequency_hz!r}: must be positive")
    measured = clock.frequency_hz
    periods = clock.pulses_used + clock.missing_pulses
    marks = 3.0 * PULSE_MARK_ERROR_SAMPLES / (periods * clock.period_samples)
    allowed = 1e6 * (Z_FINDING * clock.frequency_se_hz / measured + marks) + tolerance_ppm
    offset = 1e6 * (measured / stated_frequency_hz - 1.0)
    if abs(offset) <= allowed:
        return None
    return Finding(
        "drive_frequency",
        f"the tach runs at {measured:.7g} Hz, {offset:+.0f} ppm off the stated "
        f"{stated_frequency_hz:.7g} Hz (within {allowed:.0f} ppm would be agreement)",
        {"measured_frequency_hz": measured, "stated_frequency_hz": float(stated_frequency_hz),
         "offset_ppm": offset, "allowed_ppm": allowed,
         "measured_frequency_se_hz": clock.frequency_se_hz},
    )


def timing_finding(t_s: np.ndarray, table_m: np.ndarray, clock: StrobeClock) -> Finding | None:
    """The table channel's drive phase at the tach pulses, when it is not the 0 the tach
    marks (docs/MODEL.md section 6) by more than the noise and the pulses' sampling allow.

    The table is fitted (fundamental, second harmonic, centre) at the tach clock's
    frequency; the allowance is Z_FINDING standard errors of the two phases (the table
    fit's, honest under correlated residuals, and the clock's at its pulses' centre) plus
    the half sample by which every pulse mark may be off alike.
    """
    if clock.source != "tach":
        raise ValueError(f"a {clock.source!r} clock: timing is judged against a tach")
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(table_m, dtype=float)
    if t.shape != x.shape or t.ndim != 1:
        raise ValueError(f"t_s {t.shape} and table_m {x.shape} must be 1-D of one length")
    table = fit_table(t - t[0], x, 2.0 * math.pi * clock.frequency_hz)
    gap = math.remainder(table.phase_rad.value - clock.phase_at_start_rad, 2.0 * math.pi)
    low, high = table.phase_rad.ci95
    table_se = (high - low) / (2.0 * Z95)
    tach_se = 2.0 * math.pi * clock.centre_se_samples / clock.period_samples
    marks = 2.0 * math.pi * PULSE_MARK_ERROR_SAMPLES / clock.period_samples
    allowed = Z_FINDING * math.hypot(table_se, tach_se) + marks
    if abs(gap) <= allowed:
        return None
    delay = gap / (2.0 * math.pi * clock.frequency_hz)
    return Finding(
        "timing",
        f"the table channel is at drive phase {gap:+.3g} rad at the tach pulses "
        f"({1e3 * delay:+.3g} ms), not the 0 the tach marks (within {allowed:.2g} rad "
        "would be agreement)",
        {"phase_gap_rad": gap, "delay_s": delay, "allowed_rad": allowed,
         "table_phase_se_rad": table_se, "tach_phase_se_rad": tach_se},
    )


def backbone_finding(
    t_s: np.ndarray, angle_rad: np.ndarray, model_rad: np.ndarray, valid: np.ndarray | None,
    noise_rad: float,
) -> Finding | None:
    """A decay's frequency-amplitude relation (its backbone) against the model's curve.

    Each period runs from one upward crossing of the model's centre (its median) to the
    next: the model's from its own curve, the record's from a straight line fitted to the
    valid samples round each of its own crossings (found from the model's period).  The
    relative difference of the two frequencies, period by period, is regressed on the
    squared amplitude (a pendulum's backbone is quadratic in it); a finding when the slope
    stands Z_FINDING standard errors (from the periods' own scatter) from none and moves
    the frequency by BACKBONE_MIN or more across the record's amplitudes.
    """
    t, y, ok = _checked(t_s, angle_rad, valid)
    model = np.asarray(model_rad, dtype=float)
    if model.shape != t.shape or not np.all(np.isfinite(model)):
        raise ValueError(f"model_rad {model.shape} must be finite and match t_s {t.shape}")
    centre = float(np.median(model))
    above = model > centre
    ups = np.flatnonzero(~above[:-1] & above[1:])
    if ups.size < BACKBONE_PERIODS + 1:
        return None
    dt = float(t[1] - t[0])
    # the model's crossing times (linear between the samples either side)
    m0, m1 = model[ups] - centre, model[ups + 1] - centre
    model_cross = t[ups] + dt * m0 / (m0 - m1)
    half_window = max(3, round(float(np.median(np.diff(ups))) / 40.0))
    data_cross = np.full(ups.size, np.nan)
    cross_se = np.full(ups.size, np.nan)
    last = None  # the record's latest crossing found
    for j in range(ups.size):
        # start where the record's latest crossing and the model's periods put it (the two
        # may drift apart by more than a window over a long record), then follow the fit
        guess = model_cross[j] if last is None \
            else data_cross[last] + model_cross[j] - model_cross[last]
        for _ in range(3):
            k = int(np.clip(round((guess - t[0]) / dt), 0, t.size - 1))
            lo, hi = max(k - half_window, 0), min(k + half_window + 1, t.size)
            use = ok[lo:hi]
            if np.count_nonzero(use) < 4:
                break
            tt = t[lo:hi][use] - guess
            slope, level = np.polyfit(tt, y[lo:hi][use] - centre, 1)
            # timed only where the swing rises several noise levels across the window
            if not slope * np.ptp(tt) > 10.0 * noise_rad:
                break
            guess -= level / slope
        else:
            data_cross[j] = guess
            cross_se[j] = noise_rad / slope / math.sqrt(tt.size)
            last = j
    amplitude = np.array([0.5 * np.ptp(model[a:b + 1]) for a, b in pairwise(ups)])
    model_period = np.diff(model_cross)
    data_period = np.diff(data_cross)
    # a window that slid to a neighbouring crossing times no period
    good = np.isfinite(data_period) & (np.abs(data_period / model_period - 1.0) < 0.25) \
        & (amplitude >= BACKBONE_SMALLEST * amplitude.max())
    if np.count_nonzero(good) < BACKBONE_PERIODS:
        return None
    a2 = amplitude[good] ** 2
    mismatch = model_period[good] / data_period[good] - 1.0  # record's frequency over model's
    design = np.column_stack([np.ones_like(a2), a2 - a2.mean()])
    coef, *_ = np.linalg.lstsq(design, mismatch, rcond=None)
    scatter = mismatch - design @ coef
    dof = max(a2.size - 2, 1)
    propagated = np.hypot(cross_se[:-1], cross_se[1:])[good] / data_period[good]
    variance = max(float(scatter @ scatter) / dof, float(np.mean(propagated**2)))
    slope_se = math.sqrt(variance / float(np.sum((a2 - a2.mean()) ** 2)))
    high, low = float(amplitude[good].max()), float(amplitude[good].min())
    across = float(coef[1]) * (high**2 - low**2)
    z = abs(float(coef[1])) / slope_se
    if z <= Z_FINDING or abs(across) < BACKBONE_MIN:
        return None
    model_design = np.column_stack([np.ones_like(a2), a2])
    (f0, f2), *_ = np.linalg.lstsq(model_design, 1.0 / model_period[good], rcond=None)
    model_change = f2 * (low**2 - high**2) / (f0 + f2 * high**2)
    record_change = model_change - across
    return Finding(
        "backbone",
        f"the decay's frequency changes by {100 * record_change:+.3g} % from {high:.3g} rad "
        f"to {low:.3g} rad of swing, the model's by {100 * model_change:+.3g} % "
        f"(z = {z:.3g})",
        {"amplitude_high_rad": high, "amplitude_low_rad": low,
         "record_frequency_change": float(record_change),
         "model_frequency_change": float(model_change), "mismatch": -across, "z": z},
    )


# --- the residual's spectrum and whiteness -------------------------------------------


def _checked(t_s, residual_rad, valid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(t_s, dtype=float)
    r = np.asarray(residual_rad, dtype=float)
    if t.ndim != 1 or r.shape != t.shape:
        raise ValueError(f"t_s {t.shape} and residual_rad {r.shape} must be 1-D of one length")
    ok = np.isfinite(r)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != r.shape:
            raise ValueError(f"valid {valid.shape} must match residual_rad {r.shape}")
        ok &= valid
    if np.count_nonzero(ok) < 8 * LJUNG_BOX_LAGS:
        raise ValueError(f"{np.count_nonzero(ok)} valid residual samples: need at least "
                         f"{8 * LJUNG_BOX_LAGS} to judge whiteness")
    steps = np.diff(t)
    if not (np.all(steps > 0) and np.ptp(steps) <= 1e-6 * steps.mean()):
        raise ValueError("t_s must be uniformly sampled and increasing (gaps go in `valid`)")
    return t, np.where(ok, r, 0.0), ok


def _ljung_box(r: np.ndarray, ok: np.ndarray, lags: int) -> tuple[float, float]:
    """Ljung-Box statistic over the valid pairs at each lag (gaps never pair) and its p."""
    x = np.where(ok, r - r[ok].mean(), 0.0)
    size = sp_fft.next_fast_len(2 * x.size)
    products = sp_fft.irfft(np.abs(sp_fft.rfft(x, size)) ** 2, size)[: lags + 1]
    mask = ok.astype(float)
    pairs = np.rint(sp_fft.irfft(np.abs(sp_fft.rfft(mask, size)) ** 2, size)[: lags + 1])
    acov = products / np.maximum(pairs, 1.0)
    rho = acov[1:] / acov[0]
    n = float(pairs[0])
    q_stat = float(n * (n + 2.0) * np.sum(rho**2 / np.maximum(pairs[1:], 1.0)))
    return q_stat, float(stats.chi2.sf(q_stat, lags))


# --- lines ---------------------------------------------------------------------------


def _lines(t, r, ok, floor_rad, base_hz, drive_hz) -> list[Finding]:
    """Spectral lines off the drive's harmonics (:func:`analysis.dynamics.lines.find_lines`)
    big enough to matter, as findings, largest first."""
    out = []
    for frequency, amplitude in find_lines(t, r, ok, base_hz, max_lines=MAX_FITTED_LINES):
        if amplitude / math.sqrt(2.0) < MIN_STRUCTURE * floor_rad:
            continue
        numbers = {q.frequency_hz: frequency, "amplitude_rad": amplitude,
                   "amplitude_over_noise": amplitude / floor_rad}
        where = ""
        if drive_hz is not None:
            numbers[q.drive_frequency_hz] = float(drive_hz)
            numbers["ratio_to_drive"] = frequency / drive_hz
            where = f", not a drive harmonic (drive {drive_hz:.4g} Hz)"
        out.append(Finding("line", f"a line at {frequency:.4g} Hz, {1e3 * amplitude:.3g} mrad"
                                   f" ({amplitude / floor_rad:.2g} x the noise){where}",
                           numbers))
    return out[:MAX_LINES]


# --- trends and outliers -------------------------------------------------------------


def _trends(t, r, ok, floor_rad, model_rad) -> list[Finding]:
    """Linear drifts over the record: of the offset (the residual's level) and, with the
    model's curve, of the gain (the residual growing in proportion to the motion).

    A least-squares fit of the residual on [1, tau, m, tau m] (tau in minutes from the
    record's middle, m the model's curve less its mean) with Newey-West errors, honest
    when other structure remains; a drift is a finding at Z_FINDING standard errors
    when its rms over the record reaches MIN_STRUCTURE of the noise.
    """
    minutes = (t - 0.5 * (t[0] + t[-1])) / 60.0
    span_min = float(t[-1] - t[0]) / 60.0
    columns = [np.ones_like(t), minutes]
    motion_rms = 0.0
    if model_rad is not None:
        model = np.asarray(model_rad, dtype=float)
        if model.shape != t.shape:
            raise ValueError(f"model_rad {model.shape} must match t_s {t.shape}")
        use = ok & np.isfinite(model)
        if np.count_nonzero(use) >= 8 * LJUNG_BOX_LAGS:
            ok = use
            centred = np.where(ok, model - model[ok].mean(), 0.0)
            motion_rms = float(np.sqrt(np.mean(centred[ok] ** 2)))
            columns += [centred, minutes * centred]
    basis = np.column_stack(columns)[ok]
    coef, *_ = np.linalg.lstsq(basis, r[ok], rcond=None)
    se = np.sqrt(np.diag(sandwich_covariance([(r[ok] - basis @ coef, basis)]).matrix))
    z = coef / se
    spread = span_min / math.sqrt(12.0)  # rms of tau over the record
    out = []
    # the residual is model - data: the record drifts opposite to the residual
    offset = -float(coef[1])
    if abs(z[1]) > Z_FINDING and abs(offset) * spread >= MIN_STRUCTURE * floor_rad:
        out.append(Finding(
            "trend",
            f"the record's offset drifts by {1e3 * offset:+.3g} mrad per minute against the "
            f"model ({1e3 * offset * span_min:+.3g} mrad over the record, z = {abs(z[1]):.3g})",
            {"offset_slope_rad_per_min": offset, "z": float(abs(z[1])),
             "change_over_record_rad": offset * span_min},
        ))
    if len(coef) == 4 and motion_rms > 0:
        gain = -float(coef[3])
        if abs(z[3]) > Z_FINDING and abs(gain) * spread * motion_rms >= MIN_STRUCTURE * floor_rad:
            out.append(Finding(
                "trend",
                f"the record's gain or amplitude drifts by {100 * gain:+.3g} % per minute "
                f"against the model ({100 * gain * span_min:+.3g} % over the record, "
                f"z = {abs(z[3]):.3g})",
                {"gain_slope_per_min": gain, "z": float(abs(z[3])),
                 "change_over_record": gain * span_min},
            ))
    return out


def _outliers(t, r, ok, base_hz) -> Finding | None:
    """Heavy-tailed noise, from the residual's detail d_i = r_i - (r_{i-1} + r_{i+1}) / 2
    (smooth structure gone; exactly Gaussian for Gaussian noise).

    A finding when its spikes are heavy-tailed by the test every heavy-tail judgement
    uses (:func:`analysis.identify.preprocess.tail_spikes`: significantly more beyond
    OUTLIER_SIGMA robust standard deviations than a Gaussian puts there, carrying at
    least OUTLIER_SHARE of its sum of squares), and, on a driven record, not locked to the
    drive's phase (spikes at the impacts are a misfit of the contact, not noise): a
    Rayleigh test of the spikes' phases at each of the first PHASE_HARMONICS harmonics
    of ``base_hz`` (two impacts a period lock the second, not the first).
    """
    inner = ok[1:-1] & ok[:-2] & ok[2:]
    detail = (r[1:-1] - 0.5 * (r[:-2] + r[2:]))[inner]
    if detail.size < 8 * LJUNG_BOX_LAGS:
        return None
    spikes = tail_spikes(detail)
    if spikes is None or not spikes.heavy:
        return None
    count = spikes.count
    if base_hz is not None:
        times = t[1:-1][inner][spikes.where]
        harmonics = np.arange(1, PHASE_HARMONICS + 1)[:, None]
        phases = np.exp(2j * math.pi * base_hz * harmonics * times[None, :])
        # exp(-rayleigh) is each harmonic's p for phases spread evenly over the period
        rayleigh = count * np.abs(phases.mean(axis=1)) ** 2
        if rayleigh.max() > math.log(PHASE_HARMONICS / FALSE_ALARM):
            return None
    fraction = spikes.fraction
    kurtosis = float(stats.kurtosis(detail))
    return Finding(
        "outliers",
        f"heavy-tailed noise: {100 * fraction:.3g} % of samples beyond {OUTLIER_SIGMA:g} sigma "
        f"(a Gaussian puts {100 * GAUSSIAN_BEYOND:.2g} % there), carrying "
        f"{100 * spikes.share:.2g} % of the squared misfit; excess kurtosis {kurtosis:.3g}",
        {"fraction_beyond_5_sigma": fraction, "gaussian_fraction": GAUSSIAN_BEYOND,
         "count": float(count), "share_of_squares": spikes.share, "excess_kurtosis": kurtosis},
    )


def _why(structured, nonwhite, broadband, structured_rms, floor, noise, p, scatter,
         findings: Sequence[Finding], rms) -> str:
    """One sentence: what remains (to follow "the model still misses something: "), or
    that the residual is white noise at the record's level."""
    named = [f.sentence for f in findings if f.kind != "outliers"]
    if not structured:
        return (f"the residual is white noise at {rms / noise:.3g} x the record's noise "
                f"(no structure above {MIN_STRUCTURE:g} x its rms)")
    parts = []
    if nonwhite:
        parts.append(f"{1e3 * structured_rms:.3g} mrad rms of structure above the residual's "
                     f"white floor ({structured_rms / floor:.2g} x the noise; Ljung-Box "
                     f"p {'< 1e-15' if p < 1e-15 else f'= {p:.2g}'})")
    if broadband:
        parts.append(f"a sample-to-sample scatter {scatter:.3g} x the record's noise")
    text = " and ".join(parts)
    return text + (": " + "; ".join(named) if named else "")
