"""One axis of a map: a named quantity swept over evenly spaced values (``NAME=START:STOP:N``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAX_AXIS_POINTS = 100_000


class AxisError(ValueError):
    """An axis that cannot be swept; the message names the text and what was expected."""


@dataclass(frozen=True)
class Axis:
    """``count`` values from ``start`` to ``stop`` (both included) of the quantity ``name``."""

    name: str
    start: float
    stop: float
    count: int

    @classmethod
    def parse(cls, text: str) -> Axis:
        """``"beta=0.02:0.6:240"`` -> Axis('beta', 0.02, 0.6, 240), or AxisError saying why not."""
        name, sep, spec = text.partition("=")
        name = name.strip()
        parts = spec.split(":")
        if not sep or not name or len(parts) != 3:
            raise AxisError(f"{text!r}: expected NAME=START:STOP:N, e.g. beta=0.02:0.6:240")
        try:
            start, stop = float(parts[0]), float(parts[1])
        except ValueError:
            raise AxisError(f"{text!r}: START and STOP must be numbers") from None
        try:
            count = int(parts[2])
        except ValueError:
            raise AxisError(f"{text!r}: N = {parts[2]!r} must be a whole number") from None
        return cls(name, start, stop, count)

    def __post_init__(self) -> None:
        label = f"{self.name}={self.start:g}:{self.stop:g}:{self.count}"
        if not (math.isfinite(self.start) and math.isfinite(self.stop)):
            raise AxisError(f"{label}: START and STOP must be finite")
        if not 1 <= self.count <= MAX_AXIS_POINTS:
            raise AxisError(f"{label}: N must be between 1 and {MAX_AXIS_POINTS}")
        if self.count > 1 and self.start == self.stop:
            raise AxisError(f"{label}: START equals STOP; give N = 1 for a single value")

    @property
    def values(self) -> np.ndarray:
        """The swept values, evenly spaced, ``start`` and ``stop`` included."""
        return np.linspace(self.start, self.stop, self.count)

    def as_dict(self) -> dict[str, float | int | str]:
        """Plain values for a file's settings."""
        return {"name": self.name, "start": self.start, "stop": self.stop, "count": self.count}
