"""What flows from the acquisition engine to its subscribers besides sample and pulse blocks.

Blocks come straight from the drivers (``drivers.interfaces``); these records carry
what the engine and the procedures add: gaps, drive settings, sweep step marks (and, for
live views only, the news that a step has begun).
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.interfaces import PulseBlock, SampleBlock

COMMANDED = 0  # a setting the host sent to the amplifier
MEASURED = 1  # a setting read back from the amplifier


@dataclass(frozen=True)
class Gap:
    """Samples ``[start_index, start_index + length)`` of ``channel`` were sent but lost.

    ``outage_s > 0``: the device was away (disconnected, then reconnected) this long, and
    ``length`` is estimated from it (the device restarted its own count).
    """

    channel: str
    start_index: int
    length: int
    outage_s: float = 0.0


@dataclass(frozen=True)
class DriveSetting:
    """The shaker's drive at one moment: what was commanded or what the amplifier reported."""

    host_time_s: float
    sample_index: int
    frequency_hz: float
    amplitude_m: float
    enabled: bool
    source: int = COMMANDED


@dataclass(frozen=True)
class StepMark:
    """One step of a forced sweep: its setting and where its settle and dwell lie in the data."""

    step: int
    direction: int  # +1 going up, -1 coming down, 0 a plan's step (neither)
    frequency_hz: float
    amplitude_m: float
    settle_start_index: int
    dwell_start_index: int
    dwell_end_index: int
    complete: bool = True


@dataclass(frozen=True)
class StepBegun:
    """A sweep step has begun: news for live views, not recorded (the step's ``StepMark``,
    published when the step ends, holds all of it)."""

    step: int
    of_steps: int
    direction: int
    frequency_hz: float
    amplitude_m: float
    settle_start_index: int


Event = SampleBlock | PulseBlock | Gap | DriveSetting | StepMark | StepBegun
