"""Safety limits of the shaker drive, read from configuration and checked before anything is sent.

The limits are the lab's, tighter than the amplifier's own range: they protect the
pendulum, the barrier and the laser (100 mm range) from a typo in a procedure.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from drivers.amplifier_registers import (
    DEVICE_MAX_AMPLITUDE_UM,
    DEVICE_MAX_FREQUENCY_MHZ,
    DEVICE_MAX_RAMP_RATE_UM_S,
)
from drivers.interfaces import LimitError

RAMP_RATE_RESOLUTION_M_S = 1e-6  # the ramp-rate register counts whole micrometres per second


def _is_number(value: object) -> bool:
    """A real number (Python or numpy), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


class LimitsConfigError(ValueError):
    """The limits section of a configuration is missing a value, has an unknown key or a bad one."""


@dataclass(frozen=True)
class ShakerLimits:
    """What the host lets the shaker do (SI units); validated on construction."""

    max_amplitude_m: float = 0.010
    min_frequency_hz: float = 0.0
    max_frequency_hz: float = 50.0
    min_ramp_rate_m_s: float = 1e-6
    max_ramp_rate_m_s: float = 0.02

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not _is_number(value):
                raise LimitsConfigError(f"shaker limit {f.name} = {value!r}: expected a number")
            if not math.isfinite(value) or value < 0:
                raise LimitsConfigError(
                    f"shaker limit {f.name} = {value!r}: expected a finite number >= 0"
                )
        device = {
            "max_amplitude_m": DEVICE_MAX_AMPLITUDE_UM / 1e6,
            "max_frequency_hz": DEVICE_MAX_FREQUENCY_MHZ / 1000.0,
            "max_ramp_rate_m_s": DEVICE_MAX_RAMP_RATE_UM_S / 1e6,
        }
        for name, ceiling in device.items():
            if getattr(self, name) > ceiling:
                raise LimitsConfigError(
                    f"shaker limit {name} = {getattr(self, name)!r} exceeds the amplifier's "
                    f"own range ({ceiling})"
                )
        if self.min_frequency_hz > self.max_frequency_hz:
            raise LimitsConfigError(
                f"shaker limits: min_frequency_hz {self.min_frequency_hz} > "
                f"max_frequency_hz {self.max_frequency_hz}"
            )
        if not RAMP_RATE_RESOLUTION_M_S <= self.min_ramp_rate_m_s <= self.max_ramp_rate_m_s:
            raise LimitsConfigError(
                f"shaker limits: need {RAMP_RATE_RESOLUTION_M_S:g} (the register's resolution) "
                f"<= min_ramp_rate_m_s ({self.min_ramp_rate_m_s}) <= max_ramp_rate_m_s "
                f"({self.max_ramp_rate_m_s})"
            )

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], source: str = "configuration") -> ShakerLimits:
        """Limits from a parsed config table (TOML ``[shaker.limits]``); unknown keys refused."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise LimitsConfigError(
                f"{source}: unknown shaker limit(s) {unknown}; known: {sorted(known)}"
            )
        try:
            return cls(**dict(values))
        except LimitsConfigError as error:
            raise LimitsConfigError(f"{source}: {error}") from None

    def check(self, name: str, value: float, low: float, high: float, unit: str) -> float:
        """``value`` as float if low <= value <= high, else LimitError (nothing is sent)."""
        if not _is_number(value):
            raise LimitError(f"shaker {name} = {value!r}: expected a number in {unit}")
        value = float(value)
        if not math.isfinite(value) or not low <= value <= high:
            raise LimitError(
                f"shaker {name} = {value!r} {unit} is outside the configured limits "
                f"[{low}, {high}] {unit}; nothing was sent to the amplifier"
            )
        return value
