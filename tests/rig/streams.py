"""In-process input streams for engine and recorder tests: every sample tells its own index.

They implement ``drivers.interfaces.InputStream`` like any backend, so the engine and
the recorder are exercised through the same interface; a receiver can check sample
by sample that nothing was invented, reordered or silently dropped.
"""

from __future__ import annotations

import time

import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock, StreamStatus


def counter_values(channel_gain: float, index: np.ndarray) -> np.ndarray:
    """Calibrated value of sample ``index``: its index times a per-channel gain."""
    return index * channel_gain


class CounterStream:
    """Blocks of ``raw = index`` and ``values = gain * index``, with optional gaps.

    ``gaps`` maps a sample index to a length: those samples are skipped; when
    ``report_gaps`` the next block says so in ``lost_before`` (as a driver that
    counts lost frames would), otherwise only the index jumps.  ``realtime`` paces
    the blocks at ``sample_rate_hz``; ``total`` ends the stream (then read returns None).
    """

    def __init__(
        self,
        channel: str,
        *,
        sample_rate_hz: float = 10_000.0,
        block: int = 250,
        gain: float = 1e-3,
        total: int | None = None,
        gaps: dict[int, int] | None = None,
        report_gaps: bool = True,
        realtime: bool = False,
        first_index: int = 0,
        unit: str = "rad",
    ) -> None:
        self.channel = channel
        self.unit = unit
        self._rate = sample_rate_hz
        self.block = block
        self.gain = gain
        self.total = total
        self.gaps = dict(gaps or {})
        self.report_gaps = report_gaps
        self.realtime = realtime
        self.first_index = first_index
        self.next_index = first_index
        self.received = 0
        self.lost = 0
        self._running = False
        self._t0 = 0.0

    @property
    def sample_rate_hz(self) -> float:
        return self._rate

    def start(self) -> None:
        self._running = True
        self._t0 = time.monotonic()

    def stop(self) -> None:
        self._running = False

    def read(self, timeout_s: float = 0.1) -> SampleBlock | None:
        if not self._running or (
            self.total is not None and self.next_index >= self.first_index + self.total
        ):
            time.sleep(timeout_s)
            return None
        lost = 0
        if self.next_index in self.gaps:
            lost = self.gaps.pop(self.next_index)
            self.next_index += lost
            self.lost += lost
        n = self.block
        if self.total is not None:
            n = min(n, self.first_index + self.total - self.next_index)
        if self.realtime:
            due = self._t0 + (self.next_index + n - self.first_index) / self._rate
            wait = due - time.monotonic()
            if wait > timeout_s:
                time.sleep(timeout_s)
                return None
            if wait > 0:
                time.sleep(wait)
        index = np.arange(self.next_index, self.next_index + n, dtype=np.int64)
        # the gap itself can sit inside the block
        inside = [start for start in self.gaps if self.next_index < start < self.next_index + n]
        if inside:
            n = inside[0] - self.next_index
            index = index[:n]
        block = SampleBlock(
            channel=self.channel,
            first_index=self.next_index,
            timestamp_s=self.next_index / self._rate,
            sample_rate_hz=self._rate,
            raw=index.astype(np.int32),
            values=counter_values(self.gain, index),
            lost_before=lost if self.report_gaps else 0,
        )
        self.next_index += n
        self.received += n
        return block

    def status(self) -> StreamStatus:
        return StreamStatus(self._running, self.received, self.lost)


class TachStream:
    """Pulse blocks covering the same index ranges, with an edge every ``period`` samples."""

    def __init__(
        self,
        channel: str = "tach",
        *,
        sample_rate_hz: float = 10_000.0,
        block: int = 250,
        period: int = 1000,
        total: int | None = None,
    ) -> None:
        self.channel = channel
        self.unit = ""
        self._rate = sample_rate_hz
        self.block = block
        self.period = period
        self.total = total
        self.next_index = 0
        self._running = False

    @property
    def sample_rate_hz(self) -> float:
        return self._rate

    def start(self) -> None:
        self._running = True

    def stop(self) -> None:
        self._running = False

    def read(self, timeout_s: float = 0.1) -> PulseBlock | None:
        if not self._running or (self.total is not None and self.next_index >= self.total):
            time.sleep(timeout_s)
            return None
        n = self.block if self.total is None else min(self.block, self.total - self.next_index)
        start, end = self.next_index, self.next_index + n
        edges = np.arange(-(-start // self.period) * self.period, end, self.period, dtype=np.int64)
        self.next_index = end
        return PulseBlock(self.channel, start, end, edges, edges / self._rate)

    def status(self) -> StreamStatus:
        return StreamStatus(self._running, self.next_index, 0)
