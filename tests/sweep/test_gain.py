"""The gain where a lab looks, as the sweep's analysis states it: the baseline's and the
explained model's diagrams against the measured one in one line, and when no cause is
named, the baseline compared once and said to be the explained model."""

from __future__ import annotations

from typing import Any

import numpy as np

from analysis.sweep.analyze import SweepDiagram
from analysis.sweep.diagram import DiagramComparison, StepAgreement, regime_changes
from analysis.sweep.steps import DOWN, UP

SETTINGS = (0.04, 0.06, 0.08, 0.06, 0.04)
DIRECTIONS = (UP, UP, UP, DOWN, DOWN)
MEASURED = ("period-1", "period-2", "period-2", "period-2", "period-1")


def _comparison(name: str, simulated: tuple[str, ...]) -> DiagramComparison:
    steps = tuple(StepAgreement(k, d, s, m, x, 1.0 if m == x else 20.0)
                  for k, (d, s, m, x) in enumerate(zip(DIRECTIONS, SETTINGS, MEASURED,
                                                       simulated, strict=True)))
    return DiagramComparison(name, "amplitude", "beta", steps,
                             regime_changes(SETTINGS, DIRECTIONS, MEASURED),
                             regime_changes(SETTINGS, DIRECTIONS, simulated), (), ())


BASELINE = _comparison("baseline", ("period-1", "period-1", "period-2", "period-1",
                                    "period-1"))
EXPLAINED = _comparison("explained model", MEASURED)
NO_SWEEP: Any = None  # the summary reads no sweep


def test_summary_puts_the_baseline_beside_the_explained_model() -> None:
    diagram = SweepDiagram((), BASELINE, EXPLAINED, ("barrier_offset",), {}, NO_SWEEP, "rest")
    assert diagram.summary() == (
        "baseline: 3 of 5 steps agree, the first period-doubling at beta 0.07 against 0.05 "
        "measured; explained model: 5 of 5 steps agree, the first period-doubling at beta "
        "0.05 against 0.05 measured")
    js = diagram.as_json()
    assert js["explained_is_baseline"] is False and js["named"] == ["barrier_offset"]
    assert js["baseline"]["agreeing_steps"] == 3 and js["explained"]["agreeing_steps"] == 5
    assert [s["agrees"] for s in js["baseline"]["steps"]] == [True, False, True, False, True]
    assert np.isclose(js["baseline"]["steps"][1]["distance_in_noise"], 20.0)


def test_no_cause_named_compares_the_baseline_once_and_says_so() -> None:
    diagram = SweepDiagram((), BASELINE, None, (), {}, NO_SWEEP, "rest")
    assert [c.name for c in diagram.comparisons] == ["baseline"]
    assert diagram.summary().endswith("; no cause named: the explained model is the baseline")
    js = diagram.as_json()
    assert js["explained"] is None and js["explained_is_baseline"] is True
