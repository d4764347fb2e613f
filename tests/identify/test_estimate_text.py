"""Intervals that the fit could not compute read as words, never as numbers."""

from __future__ import annotations

import math

import pytest

from analysis.estimate_text import NOT_DETERMINED, estimate_text, interval_text


@pytest.mark.parametrize("ci95", [None, (2.856e-33, 2.856e-33), (math.nan, 1.0),
                                  (0.0, math.inf), (1.0, 1.0 + 1e-15)])
def test_an_interval_not_computed_or_of_no_width_is_not_determined(ci95):
    assert interval_text(1.0 if ci95 is None else ci95[0], ci95) == NOT_DETERMINED
    assert estimate_text(2.856e-33, ci95).endswith(f"({NOT_DETERMINED})")


def test_a_real_interval_is_printed_with_its_value():
    assert estimate_text(0.25, (0.249, 0.251)) == "0.25   95% CI [0.249, 0.251]"
    assert interval_text(3e5, (2.9e5, 3.1e5), ".3g") == "[2.9e+05, 3.1e+05]"
    # a narrow but real interval (a well-determined frequency) stays a number
    assert interval_text(13.66, (13.66 - 1e-6, 13.66 + 1e-6)) != NOT_DETERMINED
