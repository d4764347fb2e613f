"""The simulated DAQ board's firmware: command interpreter, sample clock and frame contents.

Shared by the pty emulator (which frames and sends what this produces) and the
tests' in-process backend (which hands the same chunks over directly), so the
two behave alike: same limits, same error replies, same sample indices.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.daq_protocol import (
    COMMAND_CONFIGURE,
    COMMAND_IDENTIFY,
    COMMAND_QUERY_CONFIGURATION,
    COMMAND_START,
    COMMAND_STOP,
    MAX_SAMPLES_PER_FRAME,
    BoardConfiguration,
    BoardIdentity,
    ProtocolError,
    parse_channels,
)
from hardware_sim.sample_source import SampleSource

BOARD_CLOCK_HZ = 10_000_000.0  # the sample clock is this divided by an integer
MIN_FRAMES_PER_S = 100  # a frame at least every 10 ms keeps latency low at slow rates

DEFAULT_IDENTITY = BoardIdentity(
    model="IRDAQ-4",
    serial="SIM0001",
    firmware="1.0.0",
    channels=4,
    min_rate_hz=10.0,
    max_rate_hz=250_000.0,
    adc_bits=16,
    range_v=10.0,
)

# Which source signal is wired to which analog input; unwired inputs read 0 counts.
DEFAULT_WIRING: dict[int, str] = {0: "angle", 1: "table"}
TACH_SIGNAL = "tach"  # wired to digital line 0


@dataclass(frozen=True)
class Chunk:
    """Samples the board acquired: running index of the first, counts and digital word."""

    first_index: int
    analog: np.ndarray  # (samples, channels) int16
    digital: np.ndarray  # (samples,) uint16, bit 0 = tachometer


class DaqFirmware:
    """Board state machine: identify, configure (stopped only), start, stop; makes chunks.

    Its sample clock runs ``speed`` times real time from each START (``None``: the
    source's own ``speed_factor`` if it has one, else real time; ``math.inf``:
    unpaced, samples are due as fast as they are taken).
    """

    def __init__(
        self,
        source: SampleSource,
        *,
        identity: BoardIdentity = DEFAULT_IDENTITY,
        wiring: dict[int, str] | None = None,
        max_samples_per_frame: int = 256,
        speed: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not 1 <= max_samples_per_frame <= MAX_SAMPLES_PER_FRAME:
            raise ValueError(
                f"max_samples_per_frame={max_samples_per_frame} outside 1..{MAX_SAMPLES_PER_FRAME}"
            )
        if speed is None:  # the virtual rig says how fast it should be paced
            speed = float(getattr(source, "speed_factor", 1.0))
        if not speed > 0:
            raise ValueError(f"speed={speed} must be > 0 (math.inf: unpaced)")
        self.speed = speed
        self._clock = clock
        self._started_at = 0.0
        self.source = source
        self.identity = identity
        self.wiring = dict(DEFAULT_WIRING if wiring is None else wiring)
        self.max_samples_per_frame = max_samples_per_frame
        # Power-up: input 0 at the source's own rate (within the board's limits), so that
        # merely building the board does not retime a source that is already running.
        rate = min(max(float(source.sample_rate_hz), identity.min_rate_hz), identity.max_rate_hz)
        self.configuration = self._configuration_for(rate, (0,))
        self.streaming = False
        self.next_index = 0
        if self.configuration.sample_rate_hz != source.sample_rate_hz:
            self.source.configure(self.configuration.sample_rate_hz)
        self._low = -(1 << (identity.adc_bits - 1))
        self._high = (1 << (identity.adc_bits - 1)) - 1

    def _configuration_for(self, rate_hz: float, channels: tuple[int, ...]) -> BoardConfiguration:
        divider = max(1, round(BOARD_CLOCK_HZ / rate_hz))
        actual = BOARD_CLOCK_HZ / divider
        per_frame = int(min(self.max_samples_per_frame, max(1, actual // MIN_FRAMES_PER_S)))
        return BoardConfiguration(actual, channels, per_frame)

    def handle(self, line: str) -> str:
        """Answer one command line with the reply text (``OK ...`` or ``ERR ...``)."""
        words = line.strip().split()
        if not words:
            return "ERR empty command"
        name, arguments = words[0].upper(), words[1:]
        if name == COMMAND_IDENTIFY and not arguments:
            return self.identity.to_reply()
        if name == COMMAND_QUERY_CONFIGURATION and not arguments:
            return self.configuration.to_reply()
        if name == COMMAND_CONFIGURE:
            return self._configure(arguments)
        if name == COMMAND_START and not arguments:
            if self.streaming:
                return "ERR already streaming"
            self.streaming = True
            self.next_index = 0
            self._started_at = self._clock()
            restart = getattr(self.source, "restart", None)
            if callable(restart):
                restart()
            return "OK streaming=1"
        if name == COMMAND_STOP and not arguments:
            self.streaming = False
            return f"OK streaming=0 samples={self.next_index}"
        return f"ERR unknown command {line.strip()[:40]!r}"

    def _configure(self, arguments: list[str]) -> str:
        if self.streaming:
            return "ERR busy: STOP before CONF"
        if len(arguments) != 2:
            return "ERR CONF takes a rate in Hz and a channel list, e.g. CONF 20000 0,1"
        try:
            rate_hz = float(arguments[0])
        except ValueError:
            return f"ERR rate {arguments[0]!r} is not a number"
        low, high = self.identity.min_rate_hz, self.identity.max_rate_hz
        if not low <= rate_hz <= high:
            return f"ERR rate {rate_hz:g} Hz out of range {low:g}..{high:g}"
        try:
            channels = parse_channels(arguments[1])
        except ProtocolError as error:
            return f"ERR {error}"
        if any(c >= self.identity.channels for c in channels):
            return f"ERR channel list {arguments[1]} names an input this board does not have"
        if list(channels) != sorted(channels):
            return f"ERR channel list {arguments[1]} must be in ascending order"
        self.configuration = self._configuration_for(rate_hz, channels)
        self.source.configure(self.configuration.sample_rate_hz)
        return self.configuration.to_reply()

    @property
    def paced(self) -> bool:
        """True when the sample clock keeps time (False: unpaced, ``speed`` is inf)."""
        return not math.isinf(self.speed)

    def frames_due(self) -> int:
        """Whole frames the paced clock has produced since START that are not acquired yet."""
        config = self.configuration
        elapsed = (self._clock() - self._started_at) * config.sample_rate_hz * self.speed
        return int(elapsed - self.next_index) // config.samples_per_frame

    def seconds_to_next_frame(self) -> float:
        """Wall-clock time until the paced clock completes the next frame (0 if it has)."""
        config = self.configuration
        due_s = (self.next_index + config.samples_per_frame) / (config.sample_rate_hz * self.speed)
        return max(0.0, self._started_at + due_s - self._clock())

    def acquire(self, n_samples: int | None = None) -> Chunk:
        """The next samples of the running stream (one frame's worth by default)."""
        n = self.configuration.samples_per_frame if n_samples is None else n_samples
        signals = self.source.generate(n)
        channels = self.configuration.channels
        analog = np.zeros((n, len(channels)), dtype=np.int16)
        for column, channel in enumerate(channels):
            name = self.wiring.get(channel)
            if name is not None and name in signals:
                counts = np.asarray(signals[name])
                analog[:, column] = np.clip(counts, self._low, self._high)  # the ADC saturates
        tach = signals.get(TACH_SIGNAL)
        digital = (
            np.zeros(n, dtype=np.uint16) if tach is None else np.asarray(tach).astype(np.uint16)
        )
        chunk = Chunk(self.next_index, analog, digital)
        self.next_index += n
        return chunk

    def skip(self, n_samples: int) -> None:
        """Samples acquired but never sent (a full FIFO, a hung link): the index moves on."""
        self.source.generate(n_samples)
        self.next_index += n_samples
