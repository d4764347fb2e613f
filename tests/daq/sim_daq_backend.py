"""In-process simulated DAQ backend: the board's firmware fed by a sample source, no transport.

Implements :class:`drivers.daq.DaqBackend`, so a :class:`drivers.daq.DaqBoard` and its
role drivers run unchanged on it.  It runs the same firmware model as the pty
emulator (same limits, replies and indices) and honours the same
:class:`~hardware_sim.daq_faults.DaqFaults`: a frame the faults damage is a chunk
that never arrives, exactly as the serial driver would reject it.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from drivers.daq import RawChunk
from drivers.daq_protocol import (
    COMMAND_IDENTIFY,
    COMMAND_START,
    COMMAND_STOP,
    BoardConfiguration,
    BoardIdentity,
    Reply,
    encode_configure,
    parse_reply,
)
from drivers.interfaces import DeviceError, DeviceNotFoundError
from hardware_sim.daq_faults import STALL, DaqFaults
from hardware_sim.daq_firmware import DEFAULT_IDENTITY, DaqFirmware
from hardware_sim.sample_source import SampleSource

MAX_FRAMES_PER_CHUNK = 16  # hand over up to this many frames at once when behind


class SimDaqBackend:
    """The simulated board in this process; ``speed`` scales its clock (math.inf: no pacing).

    ``speed=None`` takes the source's ``speed_factor`` when it has one (the virtual
    rig does), else real time.
    """

    def __init__(
        self,
        source: SampleSource,
        *,
        identity: BoardIdentity = DEFAULT_IDENTITY,
        speed: float | None = None,
        faults: DaqFaults | None = None,
        max_samples_per_frame: int = 256,
        wiring: dict[int, str] | None = None,
    ) -> None:
        self.firmware = DaqFirmware(
            source,
            identity=identity,
            wiring=wiring,
            max_samples_per_frame=max_samples_per_frame,
            speed=speed,
        )
        self.faults = faults if faults is not None else DaqFaults()
        self._frames_rejected = 0
        self._lock = threading.Lock()  # the reader thread acquires while the user stops

    @property
    def description(self) -> str:
        return f"simulated {self.firmware.identity.model} (in-process)"

    @property
    def frames_rejected(self) -> int:
        return self._frames_rejected

    def _ask(self, line: str, command: str) -> Reply:
        if self.faults.unplugged:
            raise DeviceError(f"the DAQ board on {self.description} went away (unplugged)")
        with self._lock:
            reply = parse_reply(self.firmware.handle(line))
        if not reply.ok:
            raise DeviceError(
                f"the DAQ board on {self.description} refused {command}: {reply.text}"
            )
        return reply

    def connect(self) -> BoardIdentity:
        if self.faults.unplugged:
            raise DeviceNotFoundError(f"{self.description} is unplugged")
        return BoardIdentity.from_reply(self._ask(COMMAND_IDENTIFY, COMMAND_IDENTIFY))

    def configure(self, sample_rate_hz: float, channels: tuple[int, ...]) -> BoardConfiguration:
        line = encode_configure(sample_rate_hz, channels).decode().strip()
        return BoardConfiguration.from_reply(self._ask(line, "CONF"))

    def start(self) -> None:
        self._ask(COMMAND_START, COMMAND_START)

    def stop(self) -> None:
        self._ask(COMMAND_STOP, COMMAND_STOP)

    def close(self) -> None:
        with self._lock:
            if self.firmware.streaming:
                self.firmware.handle(COMMAND_STOP)

    def _due_frames(self) -> int:
        return self.firmware.frames_due() if self.firmware.paced else MAX_FRAMES_PER_CHUNK

    def read_chunk(self, timeout_s: float) -> RawChunk | None:
        deadline = time.monotonic() + timeout_s
        while True:
            if self.faults.unplugged:
                raise DeviceError(f"the DAQ board on {self.description} went away (unplugged)")
            if not self.firmware.streaming:
                return None
            due = self._due_frames()
            if due and not (self.faults.stalled and not self.firmware.paced):
                with self._lock:
                    chunk = self._frames(min(due, MAX_FRAMES_PER_CHUNK))
                if chunk is not None:
                    return chunk
                continue
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            time.sleep(min(remaining, self._seconds_to_next_frame(), 0.02))

    def _seconds_to_next_frame(self) -> float:
        return self.firmware.seconds_to_next_frame() if self.firmware.paced else 0.005

    def _frames(self, count: int) -> RawChunk | None:
        """Acquire up to ``count`` frames; a lost frame ends the chunk (the next begins after)."""
        if not self.firmware.streaming:  # stopped while we waited for the lock
            return None
        per_frame = self.firmware.configuration.samples_per_frame
        good = []
        for _ in range(count):
            first = self.firmware.next_index
            if self.faults.stalled:
                self.firmware.skip(per_frame)
                self.faults.record(STALL, first, per_frame)
            elif self.faults.frame_fate(first, per_frame, per_frame).damage is not None:
                self.firmware.skip(per_frame)  # the serial driver would reject this frame
                self._frames_rejected += 1
            else:
                good.append(self.firmware.acquire())
                continue
            if good:
                break
        if not good:
            return None
        return RawChunk(
            good[0].first_index,
            np.concatenate([c.analog for c in good]),
            np.concatenate([c.digital for c in good]),
        )
