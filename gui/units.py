"""The one table of display units: files hold radians and SI, people read degrees and mm.

Every view and panel converts through :data:`DISPLAY` (value shown = SI value x factor)
and labels with its unit, so an axis, a field and a report line never disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEGREES_PER_RADIAN = 180.0 / math.pi


@dataclass(frozen=True)
class DisplayUnit:
    """How one quantity is shown: its SI unit in files, the unit on screen and the factor
    between them; ``minimum_span`` is the smallest axis span (display units) worth drawing,
    so a still signal is not blown up to fill the plot with its noise."""

    si_unit: str
    unit: str
    factor: float
    minimum_span: float

    def show(self, si_value: float | np.ndarray) -> float | np.ndarray:
        """``si_value`` (a number or an array) in display units."""
        return si_value * self.factor

    def si(self, shown: float) -> float:
        """A value entered in display units, in SI (what files and devices take)."""
        return shown / self.factor


DISPLAY: dict[str, DisplayUnit] = {
    "angle": DisplayUnit("rad", "deg", DEGREES_PER_RADIAN, 1.0),
    "angular_velocity": DisplayUnit("rad/s", "deg/s", DEGREES_PER_RADIAN, 10.0),
    "displacement": DisplayUnit("m", "mm", 1e3, 0.2),
    "length": DisplayUnit("m", "mm", 1e3, 1.0),
    "frequency": DisplayUnit("Hz", "Hz", 1.0, 1.0),
    "time": DisplayUnit("s", "s", 1.0, 0.1),
    "speed": DisplayUnit("m/s", "mm/s", 1e3, 1.0),
}

# a parameter named with its SI unit (docs/MODEL.md section 7 keys: theta_b_rad, L_m) is
# shown in that quantity's display unit; longest unit first, so "_rad_s" is not read as
# "_s".  A compound unit (Tc_N_m, mu0_s_per_m) is shown as it is.
PARAMETER_UNITS: tuple[tuple[str, str], ...] = (
    ("rad_s", "angular_velocity"),
    ("rad", "angle"),
    ("hz", "frequency"),
    ("m", "length"),
)
COMPOUND_UNIT_PARTS = frozenset({"N", "kg", "s", "per"})


def parameter_unit(name: str) -> tuple[str, DisplayUnit] | None:
    """The symbol and display unit of a parameter named ``<symbol>_<SI unit>`` (None: a
    name without a plain unit, shown as it is)."""
    for unit, quantity in PARAMETER_UNITS:
        symbol = name.removesuffix(f"_{unit}")
        if symbol != name and symbol.rsplit("_", 1)[-1] not in COMPOUND_UNIT_PARTS:
            return symbol, DISPLAY[quantity]
    return None


def axis_range(
    values: np.ndarray, minimum_span: float, margin: float = 0.05
) -> tuple[float, float] | None:
    """Axis limits around ``values``: their extent plus a margin, at least ``minimum_span``
    wide around their middle (None when there is nothing finite to show)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return None
    low, high = float(finite.min()), float(finite.max())
    span = max(high - low, minimum_span / (1.0 + 2.0 * margin))
    middle = 0.5 * (low + high)
    half = 0.5 * span * (1.0 + 2.0 * margin)
    return middle - half, middle + half

