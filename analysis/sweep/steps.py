"""A sweep: the steps a rig dwelt on, in the order it ran them, and those set aside.

A step is one drive setting held long enough to settle and then dwell; its
:class:`~analysis.records.Record` is the dwell (angle, table channel where recorded,
tach edges) with the step's drive, and ``settle_s`` says how long the rig ran at that
setting before the dwell began, so that a simulation of the sweep can be run as the rig
ran it (continued from step to step, the same settle, the same dwell).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

from analysis.records import Record

SweptParameter = Literal["amplitude", "frequency"]
UP, DOWN, UNKNOWN = 1, -1, 0  # a step's direction as the recording's /sweep_steps stores it


@dataclass(frozen=True)
class SweepStep:
    """One step of a sweep: its setting, its settle and its dwell."""

    number: int  # the step's number as recorded (0-based, in running order)
    direction: int  # UP, DOWN or UNKNOWN
    frequency_hz: float
    amplitude_m: float
    settle_s: float  # time at this setting before the dwell began
    record: Record  # the dwell, with this step's drive

    def __post_init__(self) -> None:
        if self.direction not in (UP, DOWN, UNKNOWN):
            raise ValueError(
                f"step {self.number}: direction {self.direction!r}; expected 1, -1 or 0"
            )
        if not (self.frequency_hz > 0 and self.amplitude_m >= 0 and self.settle_s >= 0):
            raise ValueError(
                f"step {self.number}: frequency {self.frequency_hz!r} Hz, amplitude "
                f"{self.amplitude_m!r} m, settle {self.settle_s!r} s; expected a frequency > 0, "
                "an amplitude >= 0 and a settle >= 0"
            )


@dataclass(frozen=True)
class SetAside:
    """A step that is not analysed, and why (interrupted, too short to judge, lost samples)."""

    number: int
    reason: str


@dataclass(frozen=True)
class Sweep:
    """The steps of one sweep in running order, and the steps set aside with their reasons."""

    source: str
    parameter: SweptParameter  # what the sweep stepped
    steps: tuple[SweepStep, ...]
    set_aside: tuple[SetAside, ...] = ()

    def __post_init__(self) -> None:
        if not self.steps:
            raise ValueError(f"{self.source or 'sweep'}: no step to analyse")
        numbers = [s.number for s in self.steps]
        if numbers != sorted(set(numbers)):
            raise ValueError(
                f"{self.source or 'sweep'}: steps {numbers} are not in running order"
            )

    def setting_aside(self, reasons: Mapping[int, str]) -> Sweep:
        """This sweep with the steps numbered in ``reasons`` set aside, each with its reason
        (ValueError, naming the sweep, when none would be left)."""
        kept = tuple(s for s in self.steps if s.number not in reasons)
        aside = tuple(sorted((*self.set_aside,
                              *(SetAside(n, why) for n, why in reasons.items())),
                             key=lambda a: a.number))
        return replace(self, steps=kept, set_aside=aside)

    def setting(self, step: SweepStep) -> float:
        """The swept parameter's value at ``step`` (m for amplitude, Hz for frequency)."""
        return step.amplitude_m if self.parameter == "amplitude" else step.frequency_hz
