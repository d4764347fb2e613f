"""What a discrepancy analysis returns: the candidates' fits and verdicts, the choice, and the
report of docs/MODEL.md section 6 (the same for every kind of experiment)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.fitting import FitData, FitResult, predict
from analysis.discrepancy.localize import Localization
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.residual_reading import Finding, ResidualReading, read_residual
from analysis.discrepancy.selection import Verdict, heldout_rms
from analysis.discrepancy.term_proposal import ProposedTerm
from analysis.experiments import KINDS
from analysis.extensions import BASELINE, NONE, ModelSpec, cause
from analysis.identify.result import Estimate
from analysis.records import Record


class AnalysisError(ValueError):
    """The record cannot be analysed; the message says why."""

    @classmethod
    def naming(cls, source: str, error: Exception) -> AnalysisError:
        """``error`` as an analysis error that names ``source`` once (an error from below
        that names it already is not prefixed again)."""
        text = str(error)
        name = source or "record"
        return cls(text if text.startswith(f"{name}:") else f"{name}: {text}")


@dataclass(frozen=True)
class CandidateOutcome:
    """A model (the baseline extended by one cause or several) fitted: training fit, full
    fit and the judges' verdict."""

    model: ModelSpec
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
    # forced records: the regime judged from the data, the drive as measured, the held-out
    # forecast error of the baseline (interleaved stretches, not one held-out tail) and the
    # model curves over the record (multiple shooting: one segment after another)
    regime: dict[str, Any] | None = None
    drive: dict[str, Any] | None = None
    baseline_heldout_rms: float | None = None
    curves: tuple[np.ndarray, np.ndarray | None] | None = None
    heldout_description: str | None = None
    # forced records: the forward selection's steps (each cause added, with the verdict of
    # its step against the model before it), the final model when it has several causes,
    # and pairs of causes the record cannot tell apart
    steps: list[tuple[str, Verdict]] = field(default_factory=list)
    final: CandidateOutcome | None = None
    indistinct: list[dict[str, Any]] = field(default_factory=list)
    # the final model's residual read for structure, and what the drive channels say
    reading: ResidualReading | None = None
    drive_findings: list[Finding] = field(default_factory=list)
    # forced records left unexplained: terms outside the named causes that the residual
    # acceleration asks for (never a cause)
    proposed_terms: list[ProposedTerm] = field(default_factory=list)
    # the rules under which it was decided
    policy: SelectionPolicy = DEFAULT_POLICY
    # decays: findings made beside the residual, which flag it as the residual's do (the
    # final model's parameters on the large swings against the rest,
    # analysis.discrepancy.constancy; a cause that would explain the record but is no real
    # rig's)
    beside: list[Finding] = field(default_factory=list)

    @property
    def chosen_outcome(self) -> CandidateOutcome | None:
        """The chosen candidate (None for ``none``)."""
        for c in self.candidates:
            if c.model.causes == (self.chosen,):
                return c
        return None

    @property
    def final_outcome(self) -> CandidateOutcome | None:
        """The model the analysis ends with: several causes, the chosen one, or None."""
        return self.final if self.final is not None else self.chosen_outcome

    @property
    def unexplained(self) -> bool:
        """True when structure is left in the final model's residual beyond the noise
        (:meth:`read` reads it)."""
        if self.reading is None:
            raise RuntimeError("Analysis.read() first: the residual is not read yet")
        return self.reading.structured

    @property
    def residual_findings(self) -> list[Finding]:
        """What the residual and the drive channels show: lines, trends, outliers, a drive
        frequency or timing off."""
        return [*(self.reading.findings if self.reading is not None else ()),
                *self.drive_findings]

    def read(self) -> Analysis:
        """Read the final model's residual (and keep the findings already made)."""
        best = self.final_outcome
        final = best.full if best is not None else self.baseline
        curve = None
        if self.curves is not None:  # forced records: the baseline's and the final model's
            curve = self.curves[0] if best is None else self.curves[1]
        backbone = KINDS[self.data.experiment].shows_backbone
        if backbone:  # a free decay: the final model's curve, for its backbone
            curve = predict(self.data, final.model, final.values)[0]
        period = (self.regime or {}).get("period") or 1
        self.reading = read_residual(
            self.data.t, final.residual, self.data.valid, self.data.noise_rad,
            drive_frequency_hz=(self.drive or {}).get(q.frequency_hz), subharmonic=period,
            model_rad=curve, backbone=backbone,
            beside=self.beside)
        return self

    def warnings(self) -> list[str]:
        """Caveats on the finding: what the chosen model still leaves unexplained."""
        out = []
        best = self.final_outcome
        if self.unexplained:
            what = f"the baseline extended by {' and '.join(best.model.causes)}" \
                if best is not None else "the baseline"
            out.append(
                f"the model still misses something: {self.reading.why} ({what}; structure "
                "outside the named causes, or a fit caught in a local minimum; treat any "
                "named cause as the best of the candidates, not the whole story)"
            )
        for c in self.ranked():
            if c.verdict.information_criterion_delta <= self.policy.bic_margin \
                    or c.model.causes == (self.chosen,):
                break
            if c.verdict.implausible:
                out.append(f"{c.model} fits the record better (BIC gain "
                           f"{c.verdict.information_criterion_delta:.3g}) but is no explanation: "
                           f"{c.verdict.implausible}")
        return out

    @property
    def shown_model(self) -> CandidateOutcome | None:
        """The extended model figures draw: the one adopted, else the best-ranked candidate
        (so a reader sees what the best one could not explain)."""
        if self.final_outcome is not None:
            return self.final_outcome
        ranked = self.ranked()
        return ranked[0] if ranked else None

    def model_curves(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The baseline's and the shown model's responses over the record (None: no model)."""
        if self.curves is not None:
            return self.curves
        base, _ = predict(self.data, BASELINE, self.baseline.values)
        shown = self.shown_model
        extended = predict(self.data, shown.model, shown.full.values)[0] if shown else None
        return base, extended

    def ranked(self) -> list[CandidateOutcome]:
        """Candidates by score (information-criterion gain), best first."""
        return sorted(self.candidates, key=lambda c: -c.verdict.information_criterion_delta)

    def selected(self) -> list[dict[str, Any]]:
        """The causes adopted, in the order they entered: each with its parameters (from the
        final model) and the gain of its step."""
        best = self.final_outcome
        if best is None:
            return []
        steps = self.steps or [(self.chosen, best.verdict)]
        return [
            {
                "cause": name,
                "parameters": cause_parameters(best.full, name),
                "gain": {
                    "information_criterion_delta": verdict.information_criterion_delta,
                    "heldout_ratio": verdict.heldout_ratio,
                    "invariant_ratio": verdict.invariant_ratio,
                },
                "verdict": verdict.why,
            }
            for name, verdict in steps
        ]

    def extended_parameters(self) -> dict[str, Any]:
        """The final model's parameters under docs/MODEL.md section 7 keys (the baseline's
        when no cause is adopted)."""
        best = self.final_outcome
        return report_parameters(best.full if best is not None else self.baseline, self.data.rig)

    def as_json(self) -> dict[str, Any]:
        """The report of docs/MODEL.md section 6, parameters keyed as section 7."""
        rig = self.data.rig
        best = self.final_outcome
        extended = best.full if best is not None else self.baseline
        baseline_heldout = self.baseline_heldout_rms if self.baseline_heldout_rms is not None \
            else heldout_rms(self.baseline_prediction, self.data.y, self.data.valid, self.n_train)
        extended_heldout = best.verdict.heldout_rms_extended if best is not None \
            else baseline_heldout
        ranking = [
            {
                "cause": c.model.name,
                "score": c.verdict.information_criterion_delta,
                "parameters": cause_parameters(c.full),
                "heldout_ratio": c.verdict.heldout_ratio,
                "invariant_ratio": c.verdict.invariant_ratio,
                "rms_residual": c.full.rms,
                "earns_keep": c.verdict.earns_keep,
                "implausible": c.verdict.implausible,
                "verdict": c.verdict.why,
                "model": {"causes": list(c.model.causes),
                          "parameters": report_parameters(c.full, rig)},
            }
            for c in self.ranked()
        ]
        out: dict[str, Any] = {
            "experiment": self.data.experiment,
            "rig": rig.as_dict(),
            "sample_rate_hz": self.record.sample_rate_hz,
            "cause": self.chosen,
            "causes": self.selected(),
            "indistinct": self.indistinct,
            "unexplained": self.unexplained,
            "residual_findings": [f.as_json() for f in self.residual_findings],
            "residual_reading": self.reading.as_json() if self.reading is not None else None,
            "proposed_terms": [term.as_json() for term in self.proposed_terms],
            "ranking": ranking,
            "baseline": {
                "parameters": report_parameters(self.baseline, rig),
                "rms_residual": self.baseline.rms,
            },
            "extended": {
                "cause": best.model.name if best is not None else NONE,
                "parameters": self.extended_parameters(),
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
            "heldout": self.heldout_description or "the record after its first "
            f"{100 * self.n_train / max(self.data.t.size, 1):.0f} % (fitted on that part)",
            "source": self.record.source,
            "notes": self.notes,
            "timings_s": self.timings,
            "policy": self.policy.as_json(),
        }
        if self.regime is not None:
            out["regime"] = self.regime
        if self.drive is not None:
            out["drive"] = self.drive
        if self.restitution is not None:
            out["restitution_comparison"] = {
                k: v for k, v in self.restitution.items()
                if k not in ("residual", "curve", "values")
            }
        return out


def cause_parameters(result: FitResult, name: str | None = None) -> dict[str, Any]:
    """The own parameters of cause ``name`` (default: every cause of the fit's model) in an
    extended fit, as {value, ci95}."""
    return {
        spec.name: result.estimates[spec.name].as_json()
        for c in ((name,) if name is not None else result.model.causes)
        for spec in cause(c).parameters
        if spec.name in result.estimates
    }


def report_parameters(result: FitResult, rig) -> dict[str, Any]:
    """All fitted parameters under docs/MODEL.md section 7 keys, with derived L and E."""
    out: dict[str, Any] = {}
    g = rig.g_m_s2
    est = result.estimates
    if q.omega_rad_s in est:
        omega = est[q.omega_rad_s]
        ci = None
        if omega.ci95 is not None and omega.ci95[0] > 0:
            ci = (g / omega.ci95[1] ** 2, g / omega.ci95[0] ** 2)
        out[q.L_m] = Estimate(g / omega.value**2, ci).as_json()
    for key, value in est.items():
        out[key] = value.as_json()
    if q.K_N_per_m1_5 in est:
        K = est[q.K_N_per_m1_5]
        factor = 3.0 / (4.0 * math.sqrt(rig.R_m))
        ci = (K.ci95[0] * factor, K.ci95[1] * factor) if K.ci95 else None
        out[q.E_Pa] = Estimate(K.value * factor, ci).as_json()
        out[q.R_m] = {"value": rig.R_m}
    if ("barrier_offset" not in result.model.causes and q.K_N_per_m1_5 in est) or q.K_n in est:
        out.setdefault(q.theta_b_rad, {"value": 0.0, "held": True})
    return out
