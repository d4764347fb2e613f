"""The tolerance a test gives a fitted value: what the method claims for it, its reported
99.9 % interval (docs/development.md, "What a test may assert").

The analysis reports 95 % intervals; a test that checks one draw against the 95 % one
fails one draw in twenty with an honest method, so it widens the interval to 99.9 %
(3.29 standard errors where the 95 % interval is 1.96).  An estimate is read as an
:class:`analysis.identify.result.Estimate` or as its JSON form ``{"value", "ci95"}``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

Z_999 = 3.29  # the 99.9 % interval's half-width in standard errors (1.96: the 95 % one)
Z_95 = 1.96


def _value_and_ci95(estimate: Any) -> tuple[float, tuple[float, float]]:
    if isinstance(estimate, Mapping):
        value, ci95 = estimate["value"], estimate.get("ci95")
    else:
        value, ci95 = estimate.value, estimate.ci95
    if ci95 is None:
        raise AssertionError(f"the estimate {estimate!r} reports no interval to test against")
    return float(value), (float(ci95[0]), float(ci95[1]))


def half_width_999(estimate: Any) -> float:
    """Half the width of the estimate's 99.9 % interval (its 95 % one widened)."""
    _value, (low, high) = _value_and_ci95(estimate)
    return (high - low) / 2.0 * Z_999 / Z_95


def within_999(estimate: Any, truth: float) -> bool:
    """``truth`` inside the estimate's reported 99.9 % interval."""
    value, _ci95 = _value_and_ci95(estimate)
    return abs(value - truth) <= half_width_999(estimate)


def resolves(estimate: Any, truth: float) -> bool:
    """The truth inside the 99.9 % interval, and that interval narrower than the effect
    (so that it excludes none, and a wrong sign fails): a tolerance never wider than the
    effect it checks."""
    return within_999(estimate, truth) and half_width_999(estimate) < abs(truth)
