"""The device interfaces every backend implements: input streams of sample blocks, and actuators.

The rest of the program (acquisition, recorder, GUI, replay) talks only to these;
it cannot tell a serial DAQ board from its emulator, an in-process simulation or
a replayed recording.  A sample is never invented: samples a device sent but the
host lost are counted and reported as a gap before the block that follows them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


class DeviceError(RuntimeError):
    """A device failed or answered wrongly; the message names the device and what happened."""


class DeviceNotFoundError(DeviceError):
    """The port or address does not exist or cannot be opened."""


class WrongDeviceError(DeviceError):
    """Something answered, but it is not the device the configuration asked for."""


class LimitError(ValueError):
    """A setting outside its configured limits; it never reached the device."""


@dataclass(frozen=True)
class SampleBlock:
    """Consecutive samples of one channel, calibrated to SI units.

    ``first_index`` is the device's running sample index of ``values[0]``;
    ``lost_before`` samples (indices ``first_index - lost_before`` to
    ``first_index - 1``) were sent by the device but lost on the way.
    """

    channel: str
    first_index: int
    timestamp_s: float  # device clock at values[0]
    sample_rate_hz: float
    raw: np.ndarray  # as received: ADC counts
    values: np.ndarray  # calibrated, SI units of the channel
    lost_before: int = 0
    flags: np.ndarray | None = None  # per-sample status bits (e.g. laser out of range)
    outage_s: float = 0.0  # the device was away this long before the block (lost_before
    # is then estimated from it: a reconnected device restarts its own count)

    def __len__(self) -> int:
        return int(self.values.size)

    @property
    def end_index(self) -> int:
        """Index one past the last sample."""
        return self.first_index + int(self.values.size)

    @property
    def times_s(self) -> np.ndarray:
        """Device time of every sample."""
        return self.timestamp_s + np.arange(self.values.size) / self.sample_rate_hz


@dataclass(frozen=True)
class PulseBlock:
    """Tachometer edges seen in the samples ``[first_index, end_index)`` of the stream."""

    channel: str
    first_index: int
    end_index: int
    edge_indices: np.ndarray  # running sample index of each rising edge
    edge_times_s: np.ndarray  # device time of each edge
    lost_before: int = 0
    outage_s: float = 0.0  # as SampleBlock.outage_s


@dataclass(frozen=True)
class StreamStatus:
    """Health of an input stream."""

    running: bool
    samples_received: int
    samples_lost: int
    frames_rejected: int = 0  # frames discarded for a bad CRC, framing or sequence
    message: str = ""  # plain words: last fault, or '' when healthy
    reconnecting: bool = False  # the device went away; the driver is trying to reach it again


@runtime_checkable
class InputStream(Protocol):
    """A streaming input: start, read blocks with a running sample index, stop."""

    channel: str
    unit: str

    @property
    def sample_rate_hz(self) -> float: ...

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def read(self, timeout_s: float = 0.1) -> SampleBlock | PulseBlock | None:
        """Next block, or None when nothing arrived within ``timeout_s``."""
        ...

    def status(self) -> StreamStatus: ...


@dataclass(frozen=True)
class ActuatorStatus:
    """What an actuator reports about itself."""

    connected: bool
    enabled: bool
    measured: dict[str, float] = field(default_factory=dict)  # e.g. amplitude_m, frequency_hz
    faults: tuple[str, ...] = ()  # plain-word names of active fault bits


@runtime_checkable
class Actuator(Protocol):
    """A device we command: validated settings, status, faults, and a safe stop."""

    def status(self) -> ActuatorStatus: ...

    def stop(self) -> None:
        """Ramp the output to zero and disable; safe to call at any time, more than once."""
        ...

    def close(self) -> None:
        """Stop the output, then release the connection."""
        ...
