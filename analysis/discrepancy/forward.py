"""The forward selection of causes, one for every kind of record: from the first cause both
judges accepted, add causes while a step earns its place, and drop an earlier cause a later
one makes redundant.

How a kind of record screens, fits and judges a model is its own (:class:`Steps`: point by
point for decays, multiple shooting for forced records); the rules of a step are the same
for every kind and read from the :class:`~analysis.discrepancy.policy.SelectionPolicy`:

1. a step is tried only while the current model's residual holds more than white noise
   (structure, or correlation beyond chance): structure too small to call the model
   unexplained can still be a second cause's;
2. every cause not yet in is screened beside the current model, and the ``step_added``
   best that gain more than ``bic_margin`` over it are fitted (a kind may refuse one whose
   screening a measurement contradicts);
3. each is fitted from the current model's optimum and afresh, the closer kept; it must gain
   more than ``bic_margin`` over the current model continued as long, be plausible, and its
   own size must differ from none (its first parameter's 95 % interval excludes the neutral
   value);
4. the best is judged against the current model by both judges, and must shrink the
   held-out error above the noise to ``heldout_excess_ratio`` (not only significantly);
5. a backward check drops an earlier cause when the model of the others alone, fitted
   already, explains the record as well (within ``bic_margin``).

A selection that starts from the baseline itself (a sweep's) takes its first cause as a
single record does (:func:`analysis.discrepancy.forced.analyze_forced_fits`): the
policy's ``refined`` best screened are fitted over the record, and judged best first until
one earns its keep, not only the best; the further steps go as above.

Causes the record cannot tell apart (:func:`indistinct`) are read from the fits' residuals
the same way for every kind.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol, TypeVar

import numpy as np

from analysis.discrepancy.policy import SelectionPolicy
from analysis.discrepancy.selection import Verdict
from analysis.extensions import ModelSpec, cause
from analysis.identify.result import Estimate
from analysis.progress import ProgressText

Fitted = TypeVar("Fitted")  # a kind's fitted model (it has ``.model``)
Fit = Any  # a kind's fit of a model over the record


class Steps(Protocol[Fitted]):
    """What a kind of record gives the forward selection."""

    def open_structure(self, current: Fitted) -> str | None:
        """None when the model's residual is white noise (no step is tried), else why not."""

    def screen(self, current: Fitted) -> dict[str, float]:
        """Every cause not in ``current`` screened beside it: its gain over ``current``."""

    def refused(self, current: Fitted, name: str) -> str | None:
        """Why cause ``name`` is not fitted beside ``current`` after its screening, or None."""

    def fit(self, current: Fitted, names: Sequence[str]) -> tuple[Fit, dict[str, Fit]]:
        """``current`` continued (the step's yardstick), and each of ``names`` added to it
        and fitted over the record (from its optimum and afresh, the closer)."""

    def gain(self, parent: Fit, fit: Fit) -> float:
        """The information-criterion gain of ``fit`` over ``parent``."""

    def disqualification(self, model: ModelSpec, fit: Fit) -> str | None:
        """Why a fitted model explains nothing whatever it gains, or None."""

    def estimates(self, fit: Fit) -> Mapping[str, Estimate]:
        """A fit's parameter estimates."""

    def full(self, fitted: Fitted) -> Fit:
        """A fitted model's fit over the record."""

    def judge(self, current: Fitted, parent: Fit, model: ModelSpec, fit: Fit
              ) -> tuple[Fitted, Verdict]:
        """Model ``model`` (``current`` and one cause more, fitted as ``fit``) judged against
        ``current`` continued as ``parent``: the fitted model and the verdict."""

    def adopted(self, fitted: Fitted, name: str | None) -> None:
        """``fitted`` is the current model now (``name``: the cause just added; None: an
        earlier cause was dropped)."""

    def alone(self, model: ModelSpec) -> Fitted | None:
        """Model ``model`` as fitted already (a single cause's), or None."""


def forward_selection(
    steps: Steps[Fitted], first: Fitted, verdict: Verdict | None, policy: SelectionPolicy,
    say: ProgressText,
) -> tuple[Fitted, list[tuple[str, Verdict]]]:
    """Causes added to ``first`` (the accepted single cause, fitted, and its ``verdict``
    against the baseline; or the baseline itself, fitted, and None: every cause is then
    taken by a step) by the rules in the module's docstring: the final fitted model, and
    the causes it holds in the order they were taken, each with its step's verdict."""
    current: Any = first
    taken: list[tuple[str, Verdict]] = \
        [(first.model.causes[0], verdict)] if verdict is not None else []
    while len(current.model.causes) < policy.max_causes:
        if (why := steps.open_structure(current)) is not None:
            say(f"  beside {current.model}: {why}; no further cause tried")
            break
        gains = steps.screen(current)
        say(f"  screened beside {current.model}: " + ", ".join(
            f"{n} {g:.3g}" for n, g in sorted(gains.items(), key=lambda kv: -kv[1])))
        first = not current.model.causes
        pool = sorted((n for n in gains if gains[n] > policy.bic_margin),
                      key=lambda n: -gains[n])[:policy.refined if first else policy.step_added]
        refused = {n: why for n in pool if (why := steps.refused(current, n))}
        for name, why in refused.items():
            say(f"  {name} not fitted over the record: its screening gives {why}")
        pool = [n for n in pool if n not in refused]
        if not pool:
            break
        parent, fits = steps.fit(current, pool)
        tried = []
        for name in pool:
            model = current.model.plus(name)
            gain = steps.gain(parent, fits[name])
            why = steps.disqualification(model, fits[name]) or \
                indeterminate(steps.estimates(fits[name]), name)
            say(f"  {model} over the record: BIC gain {gain:.3g} over {current.model}"
                + (f", but {why}" if why else ""))
            if gain > policy.bic_margin and not why:
                tried.append((gain, name))
        taking = None
        for _, name in sorted(tried, key=lambda t: -t[0])[:None if first else 1]:
            candidate, verdict = steps.judge(current, parent, current.model.plus(name),
                                             fits[name])
            say(f"  adding {name}: {verdict.why}")
            if not verdict.earns_keep:
                continue
            if verdict.heldout_excess_ratio >= policy.heldout_excess_ratio:
                say(f"  {name} not added: the held-out error above the noise shrinks only "
                    f"x{verdict.heldout_excess_ratio:.3g} (a step needs "
                    f"x{policy.heldout_excess_ratio:g})")
                continue
            taking = name
            break
        if taking is None:
            break
        name = taking
        current = candidate
        steps.adopted(candidate, name)
        taken.append((name, verdict))
        for earlier in current.model.causes[:-1]:
            rest = current.model.without(earlier)
            alone = steps.alone(rest)
            if alone is not None and \
                    steps.gain(steps.full(alone), steps.full(candidate)) <= policy.bic_margin:
                say(f"  {earlier} dropped: {rest} alone explains the record as well")
                current = alone
                steps.adopted(alone, None)
                taken = [(n, v) for n, v in taken if n != earlier]
                break
    return current, taken


def indeterminate(estimates: Mapping[str, Estimate], name: str) -> str | None:
    """Why cause ``name``'s fitted size is not known to differ from none (its first
    parameter's 95 % interval holds the neutral value), or None."""
    size = cause(name).parameters[0]
    estimate = estimates.get(size.name)
    if estimate is None or estimate.ci95 is None:
        return None
    low, high = estimate.ci95
    if low <= size.default <= high:
        return (f"its {size.name} = {estimate.value:.3g} [{low:.3g}, {high:.3g}] does not "
                f"differ from none ({size.default:g})")
    return None


def indistinct(
    accepted: str, kept: Sequence[str], base_residual: np.ndarray,
    residuals: Mapping[str, np.ndarray], gains: Mapping[str, float], policy: SelectionPolicy,
) -> list[dict[str, Any]]:
    """Causes the record cannot tell from the accepted one: their effects on the model
    curve (each single cause's residual over the record minus the baseline's, which is its
    curve minus the baseline's) correlate by the policy's ``indistinct_correlation`` or
    more, each explains the record nearly as well (``indistinct_bic`` of the accepted one's
    gain), and the forward selection did not keep both (``kept``)."""
    effect = residuals[accepted] - base_residual
    use = np.isfinite(effect)
    out = []
    for name, residual in residuals.items():
        if name in kept or name == accepted or \
                not gains[name] >= policy.indistinct_bic * gains[accepted]:
            continue
        other = residual - base_residual
        both = use & np.isfinite(other)
        a, b = effect[both], other[both]
        r = float(a @ b / math.sqrt(max((a @ a) * (b @ b), 1e-300)))
        if abs(r) >= policy.indistinct_correlation:
            out.append({
                "causes": [accepted, name], "correlation": r,
                "why": (f"{accepted} and {name} change the model's curve alike (correlation "
                        f"{r:.3f}) and explain the record nearly as well (BIC gains "
                        f"{gains[accepted]:.4g} and {gains[name]:.4g}): this record cannot "
                        f"tell them apart; {accepted} is named for its slightly higher score"),
            })
    return out
