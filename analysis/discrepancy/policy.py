"""The rules under which a record's causes are named: every threshold and cap that decides
what the discrepancy analysis names, in one frozen object with a reason for each.

An analysis takes its policy as an argument (``analyze_record(record,
policy=SelectionPolicy(bic_margin=6.0))``), every judge and every step of the forward
selection reads its thresholds from it, and the report writes it out under ``policy``
(docs/MODEL.md section 6), so a reader can tell under which rules a report was decided.
The defaults are the rules the benchmarks were measured with.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

from analysis.discrepancy import constancy, residual_reading, term_proposal


def _rule(value: float | int, why: str) -> Any:
    """A policy field: its default and the one-line reason for it."""
    return field(default=value, metadata={"why": why})


@dataclass(frozen=True)
class SelectionPolicy:
    """Every threshold and cap that decides which causes a record names (see the module)."""

    # -- the judges of one model against another
    bic_margin: float = _rule(
        10.0, "information-criterion gain a model needs over the one it extends: 'very "
        "strong' evidence on the Kass-Raftery scale")
    heldout_ratio: float = _rule(
        0.95, "the extension predicts the held-out part at least 5 % better ...")
    heldout_excess_ratio: float = _rule(
        0.9, "... or shrinks the held-out error above the noise by 10 %, significantly; a "
        "forward step must shrink it so, not only significantly (every kind of record)")
    heldout_sigmas: float = _rule(
        3.0, "where no paired test can be run (fewer than 3 held-out blocks hold samples), "
        "the held-out gain must stand this many standard errors of a noise variance clear "
        "of the scatter a finite held-out part allows")
    forecast_z: float = _rule(
        3.0, "forced records: the paired forecast test's error drop, in standard errors "
        "over the held-out stretches")
    invariant_ratio: float = _rule(
        0.7, "chaotic records without forecasts: the model's own long run must bring the "
        "invariant statistics at least 30 % closer to the record's")
    train_fraction: float = _rule(
        0.6, "decays: the first part fitted to predict the rest (the held-out judge)")
    heldout_blocks: int = _rule(
        12, "decays: the predicted rest cut into this many blocks for the paired test of "
        "the prediction's error (``forecast_z`` standard errors over the blocks)")
    viscous_floor: float = _rule(
        1e-6, "decays: a model with causes whose fitted zeta falls below this (its bound is "
        "0) is no explanation: air alone damps a real pendulum far more, and causes that "
        "take all of the rig's viscous damping stand in for a law the model lacks")
    # -- the forward selection
    max_causes: int = _rule(3, "a forward selection stops at this many causes")
    indistinct_correlation: float = _rule(
        0.9, "two causes whose effects on the model curve correlate this much ...")
    indistinct_bic: float = _rule(
        0.9, "... and of which the weaker gains at least this share of the stronger's "
        "information criterion cannot be told apart on the record: listed as indistinct")
    # -- the plausibility gate: the table channel against a drive cause fitted from the angle
    table_z: float = _rule(
        4.0, "a drive size fitted from the angle contradicts the table channel when they "
        "differ by this many standard errors of the difference ...")
    table_tolerance: float = _rule(
        0.25, "... and by this share of the larger (a model's compromise may move a size "
        "a little, not more)")
    # -- which candidates a forced record fits over the whole record, and how a step goes
    refined: int = _rule(
        4, "candidates that gained in the screening fitted over the record, best first (a "
        "forced record's, and a sweep's first step)")
    rival_screened: float = _rule(
        0.1, "once a refined cause leaves white noise, a candidate that screened this "
        "share of its gain or less is not refined (it can neither rival it nor be told "
        "apart from it)")
    rival_bic: float = _rule(
        0.5, "an unconverged fit over the record within this share of the best gain is a "
        "rival still moving, and is fitted on")
    rival_rounds: int = _rule(3, "at most this many more iteration caps for such a rival")
    seed_rms: float = _rule(
        1.2, "a fit over the record this close to the noise (times its rms) lends its "
        "segment states to the next cause's fit")
    step_added: int = _rule(
        2, "a forward step fits this many of the causes screened beside the current model "
        "over the record, best first")
    step_screen_iterations: int = _rule(
        6, "a forward step's screening: iterations of each cause added to the current "
        "model on the short segments")
    step_parent_iterations: int = _rule(
        40, "a forward step's yardstick: the current model's short fit continued this many "
        "iterations, the same for every cause")

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(f.default, int) and not isinstance(value, int):
                raise ValueError(f"policy {f.name} = {value!r}: a whole number expected")
            if not value > 0:
                raise ValueError(f"policy {f.name} = {value!r}: must be positive")
        for name in ("heldout_ratio", "heldout_excess_ratio", "train_fraction",
                     "indistinct_correlation", "indistinct_bic", "rival_screened",
                     "rival_bic"):
            if not getattr(self, name) < 1.0:
                raise ValueError(f"policy {name} = {getattr(self, name)!r}: must be below 1")

    def with_values(self, **values: float) -> SelectionPolicy:
        """This policy with ``values`` changed (names as the fields'); an unknown name is
        an error naming it."""
        known = {f.name for f in fields(self)}
        if unknown := sorted(set(values) - known):
            raise ValueError(f"policy has no rule {', '.join(unknown)}; its rules: "
                             f"{', '.join(sorted(known))}")
        return replace(self, **values)

    def changed(self) -> dict[str, float]:
        """The rules that differ from the defaults, with their values here."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) != f.default}

    def summary(self) -> str:
        """One line for a report page: the default rules, or the ones changed."""
        changed = self.changed()
        if not changed:
            return "decided under the default rules (the JSON report's `policy` lists them)"
        return "decided under rules changed from the defaults: " + ", ".join(
            f"{name} = {value:g}" for name, value in changed.items())

    @classmethod
    def from_assignments(cls, assignments: list[str]) -> SelectionPolicy:
        """The default policy with ``NAME=VALUE`` assignments applied (a command line's
        ``--rule``); a malformed one is an error naming it."""
        values: dict[str, float] = {}
        kinds = {f.name: type(f.default) for f in fields(cls)}
        for text in assignments:
            name, sep, value = text.partition("=")
            name = name.strip()
            if not sep or name not in kinds:
                raise ValueError(f"rule {text!r}: expected NAME=VALUE with NAME one of "
                                 f"{', '.join(kinds)}")
            try:
                values[name] = kinds[name](value.strip())
            except ValueError:
                raise ValueError(f"rule {text!r}: {value.strip()!r} is not "
                                 f"{'a whole number' if kinds[name] is int else 'a number'}"
                                 ) from None
        return cls().with_values(**values)

    def as_json(self) -> dict[str, Any]:
        """Each rule as ``{"value", "why"}``, and the residual reading's fixed rules under
        ``residual_reading`` (they decide ``unexplained`` and the findings), ``constancy``
        (a decay's parameters on its parts) and ``term_proposal`` (what a proposed term
        must gain)."""
        out: dict[str, Any] = {
            f.name: {"value": getattr(self, f.name), "why": f.metadata["why"]}
            for f in fields(self)
        }
        out["residual_reading"] = residual_reading.rules_json()
        out["constancy"] = constancy.rules_json()
        out["term_proposal"] = term_proposal.rules_json()
        return out


DEFAULT_POLICY = SelectionPolicy()
