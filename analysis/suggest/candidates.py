"""The competing explanations an analysis report holds, as models that can be simulated.

An ``analyze --json`` report of a forced record (docs/MODEL.md section 6) ranks every
candidate model it fitted, each with its fitted parameters and their 95 % intervals
(``ranking[].model``).  Two explanations compete when the report lists them as
``indistinct`` (the record cannot tell them apart), and the cause it named competes with
its runner-up (the best other candidate, a plausible one when there is one).
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


def competing_pairs(report: Mapping[str, Any], source: str) -> list[CompetingPair]:
    """The explanations the report leaves competing: every ``indistinct`` pair, and the
    named cause against its runner-up.  ReportError, in one line, when there is none or
    the report is not a forced record's."""
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
    entries = {entry.get("cause"): entry for entry in ranking if isinstance(entry, Mapping)}
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
    if not pairs:
        raise ReportError(f"{source}: no competing explanations to tell apart: no indistinct "
                          f"pair, and {'no cause named' if named == NONE else 'no runner-up'} "
                          "(cause " + str(named) + ")")
    return pairs
