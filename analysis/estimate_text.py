"""How an estimate and its 95 % interval read in text (summaries, reports, the GUI).

An interval the fit could not compute (none, not finite, or of no width: a parameter at
a bound or one the record does not move) says so in words; a number there would read as
a finding (``c = 2.856e-33 [2.856e-33, 2.856e-33]``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

NOT_DETERMINED = "not determined by this record"
# an interval narrower than this, relative to the value, is rounding, not knowledge: no
# record of this rig pins a parameter to better than about 1e-7 of itself
DEGENERATE_WIDTH = 1e-10


def interval_determined(value: float, ci95: Sequence[float] | None) -> bool:
    """Whether ``ci95`` is an interval worth printing around ``value``."""
    if ci95 is None or len(ci95) != 2:
        return False
    low, high = ci95
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return False
    return high - low > DEGENERATE_WIDTH * max(abs(value), abs(low), abs(high))


def interval_text(value: float, ci95: Sequence[float] | None, fmt: str = ".6g") -> str:
    """``[low, high]``, or NOT_DETERMINED."""
    if not interval_determined(value, ci95):
        return NOT_DETERMINED
    low, high = ci95  # type: ignore[misc]
    return f"[{low:{fmt}}, {high:{fmt}}]"


def estimate_text(value: float, ci95: Sequence[float] | None, fmt: str = ".6g") -> str:
    """``value 95% CI [low, high]``, or ``value (not determined by this record)``."""
    if not interval_determined(value, ci95):
        return f"{value:{fmt}} ({NOT_DETERMINED})"
    return f"{value:{fmt}}   95% CI {interval_text(value, ci95, fmt)}"
