"""The discrepancy analysis of one record: baseline fit, where it fails, every candidate cause
fitted as an extension, the choice, and the report of MODEL.md section 6.

Decays are fitted point by point: the baseline starts from ``analysis.identify``'s
estimates, every candidate from the baseline's solution with its cause neutral.
Each model is fitted on the first part of the record (to predict the rest) and
then on the whole record (parameters, intervals, information criterion).
Forced records are judged on the same residuals while the response is periodic;
a chaotic response cannot be predicted point by point, so its candidates are
compared on invariant statistics instead (:mod:`analysis.discrepancy.invariants`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from analysis.discrepancy.candidates import RecordScale, candidates_for, excluded_for
from analysis.discrepancy.fitting import FitData, FitResult, fit, predict
from analysis.discrepancy.invariants import Invariants, invariant_distance, invariants
from analysis.discrepancy.localize import Localization, localize
from analysis.discrepancy.restitution import fit_restitution, restitution_from_hunt_crossley
from analysis.discrepancy.selection import (
    Verdict,
    choose,
    heldout_rms,
    information_criterion_delta,
)
from analysis.dynamics.chaos01 import zero_one_test
from analysis.extensions import NONE, cause
from analysis.identify import IdentificationError, fit_drive, fit_free_decay, fit_impact_decay
from analysis.identify.impact_decay import impact_events
from analysis.identify.preprocess import find_bad_samples, noise_and_quantum, prepare
from analysis.identify.result import Estimate
from analysis.model import Drive
from analysis.records import Record

TRAIN_FRACTION = 0.6
UNEXPLAINED_RATIO = 5.0  # final rms this many times the noise: say the story is incomplete
CHAOTIC_FIT_PERIODS = 3  # a chaotic record is fitted only over its first drive periods
MODEL_INVARIANT_SPAN = 4  # a model's invariants come from a run this many records long
CHAOS_K = 0.8  # 0-1 test K above this: chaotic
MAX_FIT_SAMPLES = 4000
MAX_FIT_SAMPLES_WITH_CONTACT = 8000  # contacts last milliseconds: keep more samples

Progress = Callable[[str], None]


class AnalysisError(ValueError):
    """The record cannot be analysed; the message says why."""


@dataclass(frozen=True)
class CandidateOutcome:
    """One cause fitted as an extension: training fit, full fit and the judges' verdict."""

    cause: str
    train: FitResult
    full: FitResult
    verdict: Verdict
    prediction: np.ndarray  # training fit run over the whole record (held-out part included)
    rival: FitResult | None = None  # baseline refitted from this candidate's solution


@dataclass
class Analysis:
    """Everything the discrepancy analysis of one record found."""

    record: Record
    data: FitData
    n_train: int
    baseline_train: FitResult
    baseline: FitResult
    baseline_prediction: np.ndarray
    candidates: list[CandidateOutcome]
    excluded: dict[str, str]
    chosen: str
    localization: Localization
    restitution: dict[str, Any] | None = None
    zero_one_k: float | None = None  # forced records: 0-1 test K on the Poincare section
    chaotic: bool = False  # judged on invariant statistics instead of point by point
    timings: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def chosen_outcome(self) -> CandidateOutcome | None:
        """The chosen candidate (None for ``none``)."""
        for c in self.candidates:
            if c.cause == self.chosen:
                return c
        return None

    def warnings(self) -> list[str]:
        """Caveats on the finding: what the chosen model still leaves unexplained."""
        out = []
        best = self.chosen_outcome
        final = best.full if best is not None else self.baseline
        ratio = final.rms / max(self.data.noise_rad, 1e-300)
        if ratio > UNEXPLAINED_RATIO:
            what = f"the baseline extended by {best.cause}" if best is not None else "the baseline"
            out.append(
                f"{what} still leaves {final.rms:.3g} rad rms, {ratio:.3g} x the noise: "
                "structure outside the named causes (or a fit caught in a local minimum) "
                "remains; treat the named cause as the best of the candidates, not the whole story"
            )
        return out

    def ranked(self) -> list[CandidateOutcome]:
        """Candidates by score (information-criterion gain), best first."""
        return sorted(self.candidates, key=lambda c: -c.verdict.information_criterion_delta)

    def as_json(self) -> dict[str, Any]:
        """The report of MODEL.md section 6, parameters keyed as section 7."""
        rig = self.data.rig
        best = self.chosen_outcome
        extended = best.full if best is not None else self.baseline
        extended_heldout = (
            best.verdict.heldout_rms_extended if best is not None
            else heldout_rms(self.baseline_prediction, self.data.y, self.data.valid, self.n_train)
        )
        baseline_heldout = heldout_rms(
            self.baseline_prediction, self.data.y, self.data.valid, self.n_train
        )
        ranking = [
            {
                "cause": c.cause,
                "score": c.verdict.information_criterion_delta,
                "parameters": cause_parameters(c.full),
                "heldout_ratio": c.verdict.heldout_ratio,
                "invariant_ratio": c.verdict.invariant_ratio,
                "rms_residual": c.full.rms,
                "earns_keep": c.verdict.earns_keep,
                "verdict": c.verdict.why,
            }
            for c in self.ranked()
        ]
        out: dict[str, Any] = {
            "experiment": self.data.experiment,
            "cause": self.chosen,
            "ranking": ranking,
            "baseline": {
                "parameters": report_parameters(self.baseline, rig),
                "rms_residual": self.baseline.rms,
            },
            "extended": {
                "cause": self.chosen,
                "parameters": report_parameters(extended, rig),
                "rms_residual": extended.rms,
            },
            "gain": {
                "rms_reduction": 1.0 - extended.rms / self.baseline.rms
                if self.baseline.rms > 0 else 0.0,
                "heldout_rms_baseline": baseline_heldout,
                "heldout_rms_extended": extended_heldout,
                "information_criterion_delta": (
                    best.verdict.information_criterion_delta if best is not None else 0.0
                ),
            },
            "localization": self.localization.text,
            "comparison": "invariant statistics" if self.chaotic else "point by point",
            "chaos_01_K": self.zero_one_k,
            "warnings": self.warnings(),
            "localization_details": self.localization.features,
            "excluded": self.excluded,
            "noise_rad": self.data.noise_rad,
            "samples_fitted": self.data.n_valid,
            "heldout_from_s": float(self.data.t[self.n_train]) if self.n_train < self.data.t.size
            else None,
            "source": self.record.source,
            "notes": self.notes,
            "timings_s": self.timings,
        }
        if self.restitution is not None:
            out["restitution_comparison"] = {
                k: v for k, v in self.restitution.items()
                if k not in ("residual", "curve", "values")
            }
        return out


def cause_parameters(result: FitResult) -> dict[str, Any]:
    """The cause's own parameters of an extended fit, as {value, ci95}."""
    if result.cause == NONE:
        return {}
    return {
        spec.name: result.estimates[spec.name].as_json()
        for spec in cause(result.cause).parameters
        if spec.name in result.estimates
    }


def report_parameters(result: FitResult, rig) -> dict[str, Any]:
    """All fitted parameters under MODEL.md section 7 keys, with derived L and E."""
    out: dict[str, Any] = {}
    g = rig.g_m_s2
    est = result.estimates
    if "omega_rad_s" in est:
        omega = est["omega_rad_s"]
        ci = None
        if omega.ci95 is not None and omega.ci95[0] > 0:
            ci = (g / omega.ci95[1] ** 2, g / omega.ci95[0] ** 2)
        out["L_m"] = Estimate(g / omega.value**2, ci).as_json()
    for key, value in est.items():
        out[key] = value.as_json()
    if "K_N_per_m1.5" in est:
        K = est["K_N_per_m1.5"]
        factor = 3.0 / (4.0 * math.sqrt(rig.R_m))
        ci = (K.ci95[0] * factor, K.ci95[1] * factor) if K.ci95 else None
        out["E_Pa"] = Estimate(K.value * factor, ci).as_json()
        out["R_m"] = {"value": rig.R_m}
    if (result.cause != "barrier_offset" and "K_N_per_m1.5" in est) or "K_n" in est:
        out.setdefault("theta_b_rad", {"value": 0.0, "held": True})
    return out


# --------------------------------------------------------------------------- preparation


def prepare_data(record: Record, duration_s: float | None = None) -> tuple[FitData, list[str]]:
    """The fit's view of a record: release and rest trimmed (decays), bad samples out,
    decimated to at most MAX_FIT_SAMPLES samples, noise level from the full-rate data.

    ``duration_s`` (forced records) keeps only the record's first seconds, cut before the
    decimation so that a short stretch keeps the full rate its contacts need.
    """
    notes: list[str] = []
    experiment = record.experiment
    if experiment == "forced":
        valid, _, _ = find_bad_samples(record.angle_rad)
        t = record.time_s - record.time_s[0]
        y = np.where(valid, record.angle_rad, np.nan)
        noise, _ = noise_and_quantum(y)
        if duration_s is not None:
            keep = max(16, int(np.searchsorted(t, duration_s, side="right")))
            t, y, valid = t[:keep], y[:keep], valid[:keep]
    else:
        signal = prepare(record.time_s, record.angle_rad, detect_release=True)
        t, y, valid, noise = signal.time_s, signal.angle_rad, signal.valid, signal.noise_rad
        notes.extend(signal.notes)
    limit = MAX_FIT_SAMPLES if experiment == "free_decay" else MAX_FIT_SAMPLES_WITH_CONTACT
    stride = max(1, math.ceil(t.size / limit))
    if stride > 1:
        notes.append(f"fitted on every {stride}th sample ({t.size} -> {-(-t.size // stride)})")
    t, y, valid = t[::stride], y[::stride], valid[::stride].copy()
    rig = record.rig_parameters()
    drive = record.model_drive() if experiment == "forced" else Drive()
    phase0 = 0.0
    if experiment == "forced":
        drive, phase0, drive_notes = _drive_of(record, drive)
        notes.extend(drive_notes)
    data = FitData(
        experiment=experiment, t=t - t[0], y=y, valid=valid, noise_rad=float(noise), rig=rig,
        drive=drive, barrier=experiment != "free_decay", phase0_rad=phase0,
    )
    return data, notes


def _drive_of(record: Record, stated: Drive) -> tuple[Drive, float, list[str]]:
    """Drive amplitude and the drive phase at the record's first sample."""
    notes = []
    phase0 = 0.0
    if record.table_m is not None and np.isfinite(record.table_m).sum() > 16:
        result = fit_drive(record)
        phase0 = float(result["phase_rad"].value)
        notes.append("drive phase from the table channel (x_t = A sin(Omega t + phase))")
    elif record.tach_indices.size:
        t_tach = record.time_s[record.tach_indices[0]] - record.time_s[0]
        phase0 = -stated.Omega_rad_s * t_tach
        notes.append("drive phase from the tachometer pulses")
    else:
        notes.append("no table channel nor tach pulses: drive phase 0 at the first sample assumed")
    return stated, phase0, notes


def baseline_start(
    record: Record, data: FitData, priors: Mapping[str, float] | None = None
) -> tuple[dict[str, float], dict[str, float], list[str]]:
    """Start values of the baseline fit from ``analysis.identify``, and hints: identified
    values of parameters the baseline holds (sensor zero, barrier position), which start
    the candidates that free them."""
    notes: list[str] = []
    if data.experiment == "free_decay":
        result = fit_free_decay(record)
        hints = {"offset_rad": result["offset_rad"].value}
        fitted = result.details["fitted"]
        omega, zeta = result["omega_rad_s"].value, result["zeta"].value
        if "theta_dot0_rad_s" in fitted:
            theta_dot0 = float(fitted["theta_dot0_rad_s"])
        else:
            a, ph = fitted["amplitude_rad"], fitted["phase_rad"]
            theta_dot0 = -a * omega * (math.sin(ph) + zeta * math.cos(ph))
        return {
            "theta0_rad": result["theta0_rad"].value, "theta_dot0_rad_s": theta_dot0,
            "omega_rad_s": omega, "zeta": zeta,
        }, hints, notes
    if data.experiment == "impact_decay":
        try:
            result = fit_impact_decay(record)
        except (OverflowError, FloatingPointError) as error:
            # identify's interval arithmetic can overflow on a poorly determined K; its
            # impact-by-impact first estimate still gives a start
            notes.append(f"identification failed ({error}); started from the impact events")
            return (*_impact_events_start(record, data), notes)
        hints = {"offset_rad": result["offset_rad"].value,
                 "theta_b_rad": result["theta_b_rad"].value}
        fitted = result.details["fitted"]
        omega = data.rig.g_m_s2 / result["L_m"].value
        return {
            "theta0_rad": float(fitted["theta0_rad"]),
            "theta_dot0_rad_s": float(fitted["theta_dot0_rad_s"]),
            "omega_rad_s": math.sqrt(omega), "zeta": result["zeta"].value,
            "K_N_per_m1.5": result["K_N_per_m1.5"].value,
            "mu0_s_per_m": max(result["mu0_s_per_m"].value, 1e-3),
        }, hints, notes
    start = _forced_start(data, priors or {})
    # positions the decays identified (barrier, sensor zero) start the causes that free them
    hints = {k: float(v) for k, v in (priors or {}).items() if k in ("theta_b_rad", "offset_rad")}
    if not priors:
        notes.append(
            "forced record without decay records: the fit starts from L = l and the model's "
            "default contact values; pass the rig's decays (--free-decay/--impact-decay) for a "
            "start the data support"
        )
    return start, hints, notes


def _impact_events_start(
    record: Record, data: FitData
) -> tuple[dict[str, float], dict[str, float]]:
    """Start values from the free flights between impacts (identify's first estimate)."""
    signal = prepare(record.time_s, record.angle_rad, detect_release=True)
    rig = data.rig
    events = impact_events(signal, rig)
    good = np.flatnonzero(signal.valid[:5])
    y = signal.angle_rad - events["offset_rad"]
    theta_dot0 = float(np.polyfit(signal.time_s[good], y[good], 1)[0]) if good.size > 1 else 0.0
    start = {
        "theta0_rad": float(y[good[0]]), "theta_dot0_rad_s": theta_dot0,
        "omega_rad_s": float(events["omega_rad_s"]), "zeta": 0.005,
        "K_N_per_m1.5": float(events["K"]), "mu0_s_per_m": max(float(events["mu0"]), 1e-3),
    }
    hints = {"offset_rad": float(events["offset_rad"]), "theta_b_rad": float(events["theta_b_rad"])}
    return start, hints


def _forced_start(data: FitData, priors: Mapping[str, float]) -> dict[str, float]:
    """Forced records carry no decay of their own: the model values come from the rig's
    decay records (``priors``) or, failing that, L = l and the default contact values;
    the initial state from the first samples."""
    rig = data.rig
    y = data.y
    good = np.flatnonzero(data.valid[:5])
    theta0 = float(y[good[0]]) if good.size else 0.0
    theta_dot0 = float((y[good[-1]] - y[good[0]]) / ((good[-1] - good[0]) * data.dt)) \
        if good.size > 1 else 0.0
    start = {
        "theta0_rad": min(theta0, 0.0), "theta_dot0_rad_s": theta_dot0,
        "omega_rad_s": math.sqrt(rig.g_m_s2 / rig.l_m), "zeta": 0.01,
        "K_N_per_m1.5": rig.K_N_per_m1_5, "mu0_s_per_m": rig.mu0_s_per_m,
    }
    start.update({k: float(v) for k, v in priors.items() if k in start})
    return start


def priors_from_decays(
    free_decay: Record | None = None, impact_decay: Record | None = None
) -> dict[str, float]:
    """Model values identified from the rig's decay records, to start a forced-record fit."""
    priors: dict[str, float] = {}
    if free_decay is not None:
        result = fit_free_decay(free_decay)
        priors.update(omega_rad_s=result["omega_rad_s"].value, zeta=result["zeta"].value)
    if impact_decay is not None:
        hold = {"L_m": free_decay and result["L_m"].value, "zeta": priors.get("zeta")}
        result = fit_impact_decay(
            impact_decay, hold={k: v for k, v in hold.items() if v}
        )
        priors["K_N_per_m1.5"] = result["K_N_per_m1.5"].value
        priors["mu0_s_per_m"] = result["mu0_s_per_m"].value
        priors["theta_b_rad"] = result["theta_b_rad"].value
        priors["offset_rad"] = result["offset_rad"].value
        if "omega_rad_s" in result.parameters:
            priors.setdefault("omega_rad_s", result["omega_rad_s"].value)
        priors.setdefault("zeta", result["zeta"].value)
    return priors


def record_scale(data: FitData, baseline: FitResult, contacts_delta: float) -> RecordScale:
    """Magnitudes that size the candidates' steps and start values."""
    v = baseline.values
    omega = v["omega_rad_s"]
    L = data.rig.g_m_s2 / omega**2
    return RecordScale(
        amplitude_rad=float(np.nanmax(np.abs(data.y))),
        omega_rad_s=omega,
        zeta=v["zeta"],
        duration_s=float(data.t[-1]),
        dt_s=data.dt,
        inertia_kg_m2=data.rig.m_kg * L**2,
        stiffness=v.get("K_N_per_m1.5", data.rig.K_N_per_m1_5),
        mu0_s_per_m=v.get("mu0_s_per_m", data.rig.mu0_s_per_m),
        penetration_m=contacts_delta,
    )


# --------------------------------------------------------------------------- candidates


def assess_candidate(
    cause_name: str, data: FitData, n_train: int, baseline_train: FitResult,
    baseline: FitResult, baseline_heldout: float, scale: RecordScale,
    hints: dict[str, float] | None = None,
    reference: tuple[FitData, Invariants, float] | None = None,
    identified: dict[str, float] | None = None,
) -> CandidateOutcome:
    """Fit one cause on the training part and on the whole record; judge it.

    ``reference`` (chaotic records): the whole record, its invariants and the baseline's
    invariant distance; the fitted model is then also judged on its invariant statistics.
    """
    head = data.head(n_train / data.t.size)
    own = {s.name for s in cause(cause_name).parameters}
    hinted = {k: v for k, v in (hints or {}).items() if k in own}
    chaotic = reference is not None
    train = fit(head, cause_name, baseline_train.values, scale)
    if identified is not None and (hinted or chaotic):
        # The identification fitted this parameter together with the baseline's: its
        # whole solution is a second start, often in another basin than the baseline's.
        # A chaotic record's baseline fit may be a compromise far from the truth when a
        # cause acts: the rig's identified values are a second start there, over growing spans.
        first = {**identified, **hinted}
        second = fit_growing(head, cause_name, first, scale) if chaotic \
            else fit(head, cause_name, first, scale)
        if second.rms < train.rms:
            train = second
    prediction, _ = predict(data, cause_name, train.values)
    heldout = heldout_rms(prediction, data.y, data.valid, n_train)
    full = fit(data, cause_name, train.values, scale)
    distances: tuple[float | None, float | None] = (None, None)
    if reference is not None:
        whole, measured, base_distance = reference
        distances = (base_distance, model_invariant_distance(whole, measured, cause_name,
                                                              full.values))
    verdict = Verdict(
        cause=cause_name,
        information_criterion_delta=information_criterion_delta(baseline, full, data.noise_rad),
        heldout_rms_baseline=baseline_heldout,
        heldout_rms_extended=heldout,
        rms_baseline=baseline.rms,
        rms_extended=full.rms,
        invariant_distance_baseline=distances[0],
        invariant_distance_extended=distances[1],
        noise_rad=data.noise_rad,
        n_heldout=int(np.count_nonzero(data.valid[n_train:])),
    )
    rival = None
    if verdict.earns_keep:
        # Is the gain the cause's, or did its fit only find a better basin of the baseline's
        # own parameters?  Refit the baseline from the candidate's solution to find out.
        keys = set(baseline_train.values)
        rival_train = fit(head, NONE, {k: v for k, v in train.values.items() if k in keys}, scale)
        if rival_train.rms < baseline_train.rms * (1.0 - 1e-3):
            rival = rival_train
    return CandidateOutcome(cause_name, train, full, verdict, prediction, rival)


def fit_growing(
    data: FitData, cause_name: str, start: Mapping[str, float], scale: RecordScale
) -> FitResult:
    """Chaotic records: fit half a drive period, then spans doubling up to the whole of
    ``data``, each from the last solution.  Over many periods a chaotic trajectory's misfit
    has many local minima; over a short span it is smooth and pins the initial state."""
    values = dict(start)
    span = 0.5 * data.drive.period_s
    end = float(data.t[-1])
    while span < end:
        values = fit(data.head(span / end), cause_name, values, scale).values
        span *= 2.0
    return fit(data, cause_name, values, scale)


def model_invariant_distance(
    whole: FitData, measured: Invariants, cause_name: str, values: Mapping[str, float]
) -> float:
    """Distance between the record's invariants and those of the model run over
    MODEL_INVARIANT_SPAN times the record's length: a longer run pins the model's own
    statistics, so that only the record's sampling scatter stays in the distance."""
    n = MODEL_INVARIANT_SPAN * whole.t.size
    theta, _ = predict(whole, cause_name, values, n=n)
    return invariant_distance(
        measured, invariants(np.arange(n) * whole.dt, theta, whole.drive.frequency_hz,
                             whole.phase0_rad)
    )


def is_chaotic(data: FitData) -> tuple[bool, float | None]:
    """0-1 test on the record's Poincare section (needs at least 50 drive periods)."""
    if not data.drive.is_forced:
        return False, None
    measured = invariants(data.t, data.y, data.drive.frequency_hz, data.phase0_rad)
    if measured.poincare_rad.size < 50:
        return False, None
    k = float(zero_one_test(measured.poincare_rad).K)
    return k > CHAOS_K, k


def rejudge(
    outcome: CandidateOutcome, baseline: FitResult, baseline_heldout: float, data: FitData,
    reference: tuple[FitData, Invariants, float] | None,
) -> CandidateOutcome:
    """The same candidate judged against a new baseline fit."""
    v = outcome.verdict
    verdict = replace(
        v,
        information_criterion_delta=information_criterion_delta(
            baseline, outcome.full, data.noise_rad
        ),
        heldout_rms_baseline=baseline_heldout,
        rms_baseline=baseline.rms,
        invariant_distance_baseline=reference[2] if reference is not None else None,
    )
    return replace(outcome, verdict=verdict, rival=None)


def _cause_values(result: FitResult) -> dict[str, float]:
    """The cause's own parameter values, plus baseline values its parameters took over."""
    c = cause(result.cause)
    return {s.name: result.values[s.name] for s in c.parameters}


def _assess_job(args: tuple) -> CandidateOutcome:
    return assess_candidate(*args)


def analyze_record(
    record: Record, *, workers: int | None = None, progress: Progress | None = None,
    causes: list[str] | None = None, priors: Mapping[str, float] | None = None,
) -> Analysis:
    """Run the whole discrepancy analysis on one record.

    ``priors`` start the model values of a forced record (see :func:`priors_from_decays`);
    ``causes`` restricts the candidates (default: every cause that can show).
    """
    say = progress or (lambda message: None)
    clock = time.perf_counter()
    timings: dict[str, float] = {}
    data, notes = prepare_data(record)
    if data.n_valid < 50:
        raise AnalysisError(f"{record.source or 'record'}: only {data.n_valid} usable samples")
    say(f"{data.experiment}: {data.n_valid} samples at {1 / data.dt:.4g} Hz, "
        f"noise {data.noise_rad:.3g} rad")
    try:
        start, hints, start_notes = baseline_start(record, data, priors)
    except IdentificationError as error:
        raise AnalysisError(f"{record.source or 'record'}: {error}") from error
    notes.extend(start_notes)
    reference = None
    chaotic, k01 = is_chaotic(data)
    if k01 is not None:
        notes.append(f"0-1 test on the Poincare section: K = {k01:.2f}")
    if chaotic:
        whole = data
        measured = invariants(data.t, data.y, data.drive.frequency_hz, data.phase0_rad)
        # the fitted stretch is short: take it at the full rate (contacts last milliseconds)
        data, _ = prepare_data(record, CHAOTIC_FIT_PERIODS * data.drive.period_s)
        start, hints, _ = baseline_start(record, data, priors)  # initial state at full rate
        notes = [n for n in notes if not n.startswith("fitted on every")]
        say(f"chaotic (K = {k01:.2f}): fitting {data.n_valid} samples of the first "
            f"{CHAOTIC_FIT_PERIODS} drive periods, judging on invariant statistics")
        notes.append(
            f"chaotic response: models fitted over the first {CHAOTIC_FIT_PERIODS} drive periods "
            "and judged on invariant statistics (Poincare section, turning points, spectral "
            "lines) of the whole record, not point by point"
        )
    n_train = round(TRAIN_FRACTION * data.t.size)
    neutral = RecordScale(
        amplitude_rad=float(np.nanmax(np.abs(data.y))), omega_rad_s=start["omega_rad_s"],
        zeta=start["zeta"], duration_s=float(data.t[-1]), dt_s=data.dt,
        inertia_kg_m2=data.rig.m_kg * data.rig.g_m_s2**2 / start["omega_rad_s"] ** 4,
        stiffness=start.get("K_N_per_m1.5", data.rig.K_N_per_m1_5),
        mu0_s_per_m=start.get("mu0_s_per_m", data.rig.mu0_s_per_m), penetration_m=0.0,
    )
    say("fitting the baseline model")
    head = data.head(n_train / data.t.size)
    baseline_train = (fit_growing(head, NONE, start, neutral) if chaotic
                      else fit(head, NONE, start, neutral))
    baseline = fit(data, NONE, baseline_train.values, neutral)
    baseline_prediction, base_sim = predict(data, NONE, baseline_train.values)
    baseline_heldout = heldout_rms(baseline_prediction, data.y, data.valid, n_train)
    if chaotic:
        reference = (whole, measured,
                     model_invariant_distance(whole, measured, NONE, baseline.values))
    timings["baseline"] = time.perf_counter() - clock
    _, full_sim = predict(data, NONE, baseline.values)
    deltas = full_sim.contacts.delta_max_m
    scale = record_scale(data, baseline, float(np.median(deltas)) if deltas.size else 0.0)
    localization = localize(data, baseline, full_sim)
    say(f"baseline rms {baseline.rms:.3g} rad; {localization.text}")
    names = [c.name for c in candidates_for(data.experiment)]
    if causes is not None:
        names = [n for n in names if n in causes]
    jobs = [
        (n, data, n_train, baseline_train, baseline, baseline_heldout, scale, hints, reference,
         start)
        for n in names
    ]
    workers = workers if workers is not None else min(2, os.cpu_count() or 1)
    outcomes: list[CandidateOutcome] = []
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for outcome in pool.map(_assess_job, jobs):
                say(f"  {outcome.cause}: {outcome.verdict.why}")
                outcomes.append(outcome)
    else:
        for job in jobs:
            outcome = _assess_job(job)
            say(f"  {outcome.cause}: {outcome.verdict.why}")
            outcomes.append(outcome)
    rivals = [o.rival for o in outcomes if o.rival is not None]
    if rivals:
        better = min(rivals, key=lambda r: r.rms)
        say(f"a candidate's solution led the baseline to a better fit (training rms "
            f"{better.rms:.3g} rad against {baseline_train.rms:.3g}): judging again")
        notes.append("the baseline was refitted from a candidate's solution (better basin)")
        baseline_train = better
        baseline = fit(data, NONE, baseline_train.values, neutral)
        baseline_prediction, base_sim = predict(data, NONE, baseline_train.values)
        baseline_heldout = heldout_rms(baseline_prediction, data.y, data.valid, n_train)
        if reference is not None:
            reference = (whole, measured,
                         model_invariant_distance(whole, measured, NONE, baseline.values))
        outcomes = [rejudge(o, baseline, baseline_heldout, data, reference) for o in outcomes]
        _, full_sim = predict(data, NONE, baseline.values)
        localization = localize(data, baseline, full_sim)
    timings["candidates"] = time.perf_counter() - clock - timings["baseline"]
    verdict = choose([o.verdict for o in outcomes])
    chosen = verdict.cause if verdict is not None else NONE
    analysis = Analysis(
        record=record, data=data, n_train=n_train, baseline_train=baseline_train,
        baseline=baseline, baseline_prediction=baseline_prediction, candidates=outcomes,
        excluded=excluded_for(data.experiment), chosen=chosen, localization=localization,
        timings=timings, notes=notes, zero_one_k=k01, chaotic=chaotic,
    )
    if data.experiment == "impact_decay":
        say("constant coefficient of restitution against Hunt-Crossley")
        analysis.restitution = compare_restitution(data, n_train, baseline, baseline_heldout,
                                                   base_sim)
    timings["total"] = time.perf_counter() - clock
    say(f"cause: {chosen} ({timings['total']:.1f} s)")
    return analysis


def compare_restitution(
    data: FitData, n_train: int, baseline: FitResult, baseline_heldout: float, sim
) -> dict[str, Any]:
    """The paper's case: instantaneous impacts with constant e against Hunt-Crossley contact."""
    v = baseline.values
    speeds = np.abs(sim.contacts.theta_dot_in)
    speed = float(np.median(speeds)) if speeds.size else abs(v["omega_rad_s"] * v["theta0_rad"])
    e0 = restitution_from_hunt_crossley(v["mu0_s_per_m"], data.rig.l_m, speed)
    if sim.contacts.count >= 2:
        ratios = np.abs(sim.contacts.theta_dot_out / sim.contacts.theta_dot_in)
        e0 = float(np.clip(np.median(ratios), 0.05, 0.99))
    start = {**v, "e": e0}
    result = fit_restitution(data.t, data.y, data.valid, start, n_train)
    residual = result["residual"]
    rss = result["rss"]
    r = residual[np.isfinite(residual)]
    rms = float(math.sqrt(np.mean(r * r)))
    # Same judges as the candidates: positive values favour Hunt-Crossley.
    fake = FitResult("restitution", result["values"], {}, residual, result["n_params"], True, "")
    ic = information_criterion_delta(fake, baseline, data.noise_rad)
    return {
        "model": "instantaneous impacts at theta = 0 with constant coefficient of restitution e",
        "parameters": result["parameters"],
        "rms_residual": rms,
        "rss": rss,
        "heldout_rms": result["heldout_rms"],
        "hunt_crossley_rms_residual": baseline.rms,
        "hunt_crossley_heldout_rms": baseline_heldout,
        "rms_reduction_by_hunt_crossley": 1.0 - baseline.rms / rms if rms > 0 else 0.0,
        "information_criterion_delta_for_hunt_crossley": ic,
        "residual": residual,
        "curve": result["curve"],
        "values": result["values"],
    }
