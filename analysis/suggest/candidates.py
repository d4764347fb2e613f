"""The competing explanations an analysis report holds, as models that can be simulated.

An ``analyze --json`` report of a forced record (docs/MODEL.md section 6) ranks every
candidate model it fitted, each with its fitted parameters and their 95 % intervals
(``ranking[].model``).  Two explanations compete when the report lists them as
``indistinct`` (the record cannot tell them apart), and the cause it named competes with
its runner-up (the best other candidate, a plausible one when there is one).  The
best-ranked candidate (a plausible one when there is one) competes with the next ones the
record ranks within the report's information criterion margin of it (``policy.bic_margin``;
at most ``RIVALS`` in all): the record's scores do not tell them apart.  The report's
baseline (its ``baseline`` section) competes as an explanation of its own: when the report
names no cause, against each of those best-ranked candidates; when the finding it names is
weak (:func:`weak_finding`: the report flags it), against the cause named.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.extensions import NONE, cause
from analysis.identify.forced import BASELINE_PLANS
from analysis.identify.intervals import Z95
from analysis.model import RigParameters

# the baseline's parameters a candidate model is built from: those the forced fit adjusts
RIG_KEYS = tuple(BASELINE_PLANS)
# a 95 % interval spans 2 x Z95 standard deviations of a normal estimate
CI95_WIDTH_IN_SD = 2.0 * Z95
# the best-ranked candidate and the next ones within the report's BIC margin of it, at most
# this many in all: set against each other, and each against the baseline when nothing is
# named
RIVALS = 2
BASELINE = "baseline"  # the name the baseline competes under


class ReportError(ValueError):
    """A report suggest cannot use; the message names it and says what is missing."""


@dataclass(frozen=True)
class Candidate:
    """One explanation: a model (its causes), its fitted values and their 95 % intervals."""

    name: str
    causes: tuple[str, ...]
    values: Mapping[str, float]  # model_from_values keys: the rig's and the causes' own
    intervals: Mapping[str, tuple[float, float]]  # the values that have one
    theta_b_rad: float = 0.0  # the barrier, when no cause of the model places it

    def draws(self, count: int, seed: Sequence[int]) -> list[dict[str, float]]:
        """``count`` parameter sets drawn within the intervals: each value with an interval
        independently normal about the fitted value (the interval's width as 2 x 1.96
        standard deviations), clipped to the interval and to the cause's bounds; the same
        sets for the same ``seed``.  Independent draws ignore the estimates' correlations,
        so they spread the predictions more than the fit's covariance would: a difference
        counted against them is counted conservatively."""
        rng = np.random.default_rng(list(seed))
        bounds = _bounds(self.causes)
        out = []
        for _ in range(count):
            drawn = dict(self.values)
            for key, (low, high) in sorted(self.intervals.items()):
                sd = (high - low) / CI95_WIDTH_IN_SD
                value = float(np.clip(rng.normal(self.values[key], sd), low, high))
                lower, upper = bounds.get(key, (-math.inf, math.inf))
                drawn[key] = min(max(value, lower), upper)
            out.append(drawn)
        return out


@dataclass(frozen=True)
class CompetingPair:
    """Two explanations a new experiment should tell apart, and why they compete."""

    first: Candidate
    second: Candidate
    why: str

    @property
    def label(self) -> str:
        """'barrier_offset vs sensor_offset'."""
        return f"{self.first.name} vs {self.second.name}"


def _bounds(causes: Sequence[str]) -> dict[str, tuple[float, float]]:
    # the forced fit's bounds: the report's candidates were fitted within them
    out = {name: (low, high) for name, (_, _, low, high) in BASELINE_PLANS.items()}
    for name in causes:
        for spec in cause(name).parameters:
            out[spec.name] = (spec.lower, spec.upper)
    return out


def report_rig(report: Mapping[str, Any], source: str) -> RigParameters:
    """The rig the report's models were built on (its ``rig``)."""
    rig = report.get("rig")
    if not isinstance(rig, Mapping):
        raise ReportError(f"{source}: no 'rig' section (made by an older impact-rig?); "
                          "analyse the record again with 'impact-rig analyze --json'")
    try:
        return RigParameters(**{k: float(v) for k, v in rig.items()})
    except (TypeError, ValueError) as error:
        raise ReportError(f"{source}: rig: {error}") from None


def candidate(entry: Mapping[str, Any], source: str) -> Candidate:
    """The ranking entry's model as a :class:`Candidate`."""
    name = entry.get("cause", "?")
    model = entry.get("model")
    if not isinstance(model, Mapping) or "parameters" not in model:
        raise ReportError(f"{source}: ranking entry {name!r} holds no fitted model (made by "
                          "an older impact-rig?); analyse the record again with "
                          "'impact-rig analyze --json'")
    causes = tuple(str(c) for c in model.get("causes", ()))
    parameters = model["parameters"]
    keys = list(RIG_KEYS) + [spec.name for c in causes for spec in cause(c).parameters]
    values: dict[str, float] = {}
    intervals: dict[str, tuple[float, float]] = {}
    for key in keys:
        estimate = parameters.get(key)
        if not isinstance(estimate, Mapping) or estimate.get("value") is None:
            continue
        values[key] = float(estimate["value"])
        ci = estimate.get("ci95")
        if ci is not None and None not in ci and not estimate.get("held"):
            low, high = float(ci[0]), float(ci[1])
            if math.isfinite(low) and math.isfinite(high) and low <= values[key] <= high:
                intervals[key] = (low, high)
    for key in (q.omega_rad_s, q.zeta):
        if key not in values:
            raise ReportError(f"{source}: ranking entry {name!r}: its model has no {key}")
    barrier = parameters.get(q.theta_b_rad) or {}
    theta_b = 0.0 if "barrier_offset" in causes else float(barrier.get("value") or 0.0)
    return Candidate(str(name), causes, values, intervals, theta_b)


def baseline_candidate(report: Mapping[str, Any], source: str) -> Candidate:
    """The report's baseline model (its ``baseline`` section) as a :class:`Candidate` with
    no cause, named ``baseline``."""
    baseline = report.get("baseline")
    if not isinstance(baseline, Mapping) or not isinstance(baseline.get("parameters"), Mapping):
        raise ReportError(f"{source}: no 'baseline' parameters: not an 'impact-rig analyze "
                          "--json' report")
    return candidate({"cause": BASELINE, "model": {"causes": [],
                                                   "parameters": baseline["parameters"]}},
                     source)


def _policy_value(report: Mapping[str, Any], rule: str) -> float | None:
    value = ((report.get("policy") or {}).get(rule) or {}).get("value")
    return float(value) if isinstance(value, int | float) else None


def best_ranked(report: Mapping[str, Any],
                ranking: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The best-ranked candidates (plausible ones when there are any): the first, and the
    next ones within the report's BIC margin of it (``policy.bic_margin``; none without
    it), at most ``RIVALS``."""
    plausible = [e for e in ranking if not e.get("implausible")]
    ranked = plausible or list(ranking)
    if not ranked:
        return []
    margin = _policy_value(report, "bic_margin")
    best = ranked[0].get("score")
    out = [ranked[0]]
    for entry in ranked[1:RIVALS]:
        score = entry.get("score")
        if not all(isinstance(v, int | float) for v in (margin, best, score)) \
                or best - score > margin:
            break
        out.append(entry)
    return out


def weak_finding(report: Mapping[str, Any]) -> str | None:
    """Why the cause a report names is a weak finding, from what the report flags: the
    model still misses something (``unexplained``), the analysis warned, or the cause
    earned its place only on the held-out error above the noise, its held-out error
    falling by less than the policy's clear gain (its first step's ``heldout_ratio`` above
    ``policy.heldout_ratio``).  None when the report names nothing or flags nothing."""
    named = report.get("cause", NONE)
    if named == NONE:
        return None
    if report.get("unexplained"):
        return "the report says the model still misses something"
    warnings = [str(w) for w in report.get("warnings") or []]
    if warnings:
        return f"the report warns: {warnings[0]}"
    steps = [c for c in report.get("causes") or [] if isinstance(c, Mapping)]
    ratio = ((steps[0].get("gain") or {}).get("heldout_ratio")) if steps else None
    clear = _policy_value(report, "heldout_ratio")
    if isinstance(ratio, int | float) and clear is not None and ratio > clear:
        return (f"its held-out error x{ratio:.3g}, short of the clear gain (x{clear:g} or "
                "less)")
    return None


def _forced_ranking(report: Mapping[str, Any], source: str) -> list[Mapping[str, Any]]:
    """The ranking of a forced record's report; ReportError for any other report."""
    if report.get("kind") == "sweep":
        raise ReportError(f"{source}: a sweep's report; suggest reads the report of one "
                          "forced record (sweeps are not searched yet)")
    if report.get("experiment") != "forced":
        raise ReportError(f"{source}: a {report.get('experiment', 'unknown')!r} record's "
                          "report; suggest searches forced steps, from a forced record's "
                          "report")
    ranking = report.get("ranking")
    if not isinstance(ranking, list):
        raise ReportError(f"{source}: no 'ranking': not an 'impact-rig analyze --json' report")
    return [entry for entry in ranking if isinstance(entry, Mapping)]


def competing_pairs(report: Mapping[str, Any], source: str) -> list[CompetingPair]:
    """The explanations the report leaves competing: every ``indistinct`` pair, the named
    cause against its runner-up, the best-ranked candidates within the BIC margin against
    each other, and the baseline against the best-ranked candidate(s) when no cause is
    named, or against the named cause when the finding is weak (:func:`weak_finding`).
    ReportError, in one line, when there is none or the report is not a forced record's."""
    ranking = _forced_ranking(report, source)
    entries = {entry.get("cause"): entry for entry in ranking}
    pairs: list[CompetingPair] = []
    seen: set[frozenset[str]] = set()

    def add(a: str, b: str, why: str) -> None:
        key = frozenset((a, b))
        if key in seen:
            return
        for name in (a, b):
            if name not in entries:
                raise ReportError(f"{source}: {name!r} competes ({why}) but has no entry in "
                                  "the ranking")
        seen.add(key)
        pairs.append(CompetingPair(candidate(entries[a], source),
                                   candidate(entries[b], source), why))

    for pair in report.get("indistinct") or []:
        a, b = pair["causes"]
        add(a, b, pair.get("why") or "indistinct")
    named = report.get("cause", NONE)
    if named != NONE and named in entries:
        others = [e for e in ranking if e.get("cause") != named]
        plausible = [e for e in others if not e.get("implausible")]
        runner_up = (plausible or others or [None])[0]
        if runner_up is not None:
            add(named, runner_up["cause"],
                f"{named} is named; {runner_up['cause']} is its runner-up")
    rivals = best_ranked(report, ranking)
    if named == NONE and rivals:
        baseline = baseline_candidate(report, source)
        for number, entry in enumerate(rivals):
            name = entry.get("cause")
            why = (f"nothing named; the best-ranked candidate {name} against the baseline"
                   if number == 0 else
                   f"nothing named; {name}, ranked within the BIC margin of the best, "
                   "against the baseline")
            pairs.append(CompetingPair(baseline, candidate(entry, source), why))
    for entry in rivals[1:]:
        add(rivals[0]["cause"], entry["cause"],
            f"{entry['cause']} ranked within the BIC margin of {rivals[0]['cause']}")
    weak = weak_finding(report)
    if weak is not None and named in entries:
        pairs.append(CompetingPair(candidate(entries[named], source),
                                   baseline_candidate(report, source),
                                   f"{named} is named, weakly ({weak}); against the baseline"))
    if not pairs:
        lacking = "no cause named and no candidate ranked" if named == NONE \
            else "no runner-up"
        raise ReportError(f"{source}: no competing explanations to tell apart: no indistinct "
                          f"pair, and {lacking} (cause {named})")
    return pairs
