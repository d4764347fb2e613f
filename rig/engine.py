"""The acquisition engine: reads every input stream in its own thread and fans the blocks out.

Consumers never block acquisition.  Each subscriber has its own bounded queue: a slow
viewer loses part of its own view (counted per subscriber), never anyone else's data.
The recorder subscribes as *privileged*: it is never dropped from; if it falls too far
behind, the engine fails loudly (``SubscriberOverrunError``) instead of losing samples.
Gaps (samples the device sent but the host lost, whether the driver reported them or
the index jumped) are counted and published as ``Gap`` events before the next block.
A stream whose device went away and is being reached again says so in its status; the
engine shows it (``EngineStats.reconnecting``), logs it, and the first block after the
outage comes with a ``Gap`` that carries the outage's length.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

from drivers.interfaces import InputStream, SampleBlock
from rig.events import COMMANDED, DriveSetting, Event, Gap, StepBegun, StepMark

Delivery = tuple[float, Event]  # (host time since the engine started, event)

DEFAULT_VIEW_ITEMS = 2000
DEFAULT_PRIVILEGED_BACKLOG_SAMPLES = 20_000_000  # about 25 s of 4 channels at 200 kHz
RATE_WINDOW_S = 2.0

log = logging.getLogger("impact_rig.acquisition")


class AcquisitionError(RuntimeError):
    """An input stream failed; the message names the channel and what happened."""


class SubscriberOverrunError(RuntimeError):
    """A privileged subscriber (the recorder) fell too far behind; acquisition stops rather than
    lose samples from the recording."""


def _samples_in(event: Event) -> int:
    return len(event) if isinstance(event, SampleBlock) else 0


class Subscription:
    """One consumer's queue of ``(host_time_s, event)`` deliveries.

    An ordinary subscription holds at most ``max_items``; when full the oldest item is
    dropped (and counted) so a viewer always sees the newest data.  A privileged one
    keeps everything up to ``max_backlog_samples`` and reports an overrun past that.
    """

    def __init__(
        self,
        name: str,
        *,
        max_items: int = DEFAULT_VIEW_ITEMS,
        privileged: bool = False,
        max_backlog_samples: int = DEFAULT_PRIVILEGED_BACKLOG_SAMPLES,
    ) -> None:
        if max_items < 1:
            raise ValueError(f"subscription {name!r}: max_items must be at least 1")
        self.name = name
        self.privileged = privileged
        self.max_items = max_items
        self.max_backlog_samples = max_backlog_samples
        self.dropped_items = 0
        self.dropped_samples = 0
        self._items: deque[Delivery] = deque()
        self._backlog_samples = 0
        self._ready = threading.Condition(threading.Lock())
        self._closed = False

    def put(self, delivery: Delivery) -> bool:
        """Queue a delivery without ever blocking; False when a privileged queue overran."""
        samples = _samples_in(delivery[1])
        with self._ready:
            if self._closed:
                return True
            if self.privileged:
                if self._backlog_samples + samples > self.max_backlog_samples:
                    self.dropped_items += 1  # refused, not queued: counted like a viewer's loss
                    self.dropped_samples += samples
                    return False
            elif len(self._items) >= self.max_items:
                _, old = self._items.popleft()
                lost = _samples_in(old)
                self._backlog_samples -= lost
                self.dropped_items += 1
                self.dropped_samples += lost
            self._items.append(delivery)
            self._backlog_samples += samples
            self._ready.notify()
        return True

    def get(self, timeout_s: float = 0.1) -> Delivery | None:
        """The oldest delivery, or None when nothing came within ``timeout_s``."""
        batch = self.get_many(timeout_s, max_items=1)
        return batch[0] if batch else None

    def get_many(self, timeout_s: float = 0.1, max_items: int | None = None) -> list[Delivery]:
        """Everything queued (up to ``max_items``), waiting up to ``timeout_s`` for the first."""
        with self._ready:
            if not self._items and not self._closed:
                self._ready.wait(timeout_s)
            count = len(self._items) if max_items is None else min(max_items, len(self._items))
            batch = [self._items.popleft() for _ in range(count)]
            self._backlog_samples -= sum(_samples_in(event) for _, event in batch)
            return batch

    @property
    def backlog_items(self) -> int:
        """Deliveries waiting to be taken."""
        return len(self._items)

    @property
    def closed(self) -> bool:
        """True once the engine stopped and everything queued was taken."""
        return self._closed and not self._items

    def close(self) -> None:
        """No more deliveries will come (the engine stopped); wakes a waiting reader."""
        with self._ready:
            self._closed = True
            self._ready.notify_all()


@dataclass
class ChannelStats:
    """Live health of one input channel."""

    channel: str
    blocks: int = 0
    samples_received: int = 0  # samples (or covered indices, for pulse channels)
    samples_lost: int = 0
    gaps: int = 0
    index_regressions: int = 0  # blocks that started before the previous one ended
    end_index: int | None = None
    sample_rate_hz: float = 0.0  # estimated from arrivals over the last seconds
    edges: int = 0
    last_edge_times_s: tuple[float, ...] = ()
    pulse: bool = False  # a pulse (tach) stream: its lost indices are not samples
    reconnecting: bool = False  # its device went away; the driver is reaching it again
    outages: int = 0  # times its device went away and came back
    message: str = ""  # the stream's own last word on its health

    @property
    def tach_frequency_hz(self) -> float | None:
        """Frequency from the last two tach edges, for pulse channels."""
        if len(self.last_edge_times_s) < 2:
            return None
        period = self.last_edge_times_s[-1] - self.last_edge_times_s[-2]
        return 1.0 / period if period > 0 else None


@dataclass(frozen=True)
class SubscriberStats:
    """What one subscriber lost of its own view, and what waits in its queue."""

    name: str
    privileged: bool
    dropped_items: int
    dropped_samples: int
    backlog_items: int


@dataclass(frozen=True)
class EngineStats:
    """A snapshot of the live quantities subscribers and displays want."""

    host_time_s: float
    channels: dict[str, ChannelStats]
    subscribers: tuple[SubscriberStats, ...]
    drive: DriveSetting | None
    latest_index: int | None
    aligned_end_index: int | None
    error: str = ""

    @property
    def reconnecting(self) -> tuple[str, ...]:
        """Channels whose device went away and is being reached again (empty when none)."""
        return tuple(name for name, c in self.channels.items() if c.reconnecting)

    @property
    def samples_lost(self) -> int:
        """Samples lost by the sampled streams (the tach stream's lost indices apart: they
        are the same board samples again, not samples of their own)."""
        return sum(c.samples_lost for c in self.channels.values() if not c.pulse)

    @property
    def lost_per_stream(self) -> dict[str, int]:
        """Samples (for the tach stream: covered indices) lost, per stream."""
        return {name: c.samples_lost for name, c in self.channels.items()}


@dataclass
class _RateWindow:
    arrivals: deque = field(default_factory=deque)

    def add(self, host_time_s: float, end_index: int) -> float:
        self.arrivals.append((host_time_s, end_index))
        while len(self.arrivals) > 2 and host_time_s - self.arrivals[0][0] > RATE_WINDOW_S:
            self.arrivals.popleft()
        (t0, i0), (t1, i1) = self.arrivals[0], self.arrivals[-1]
        return (i1 - i0) / (t1 - t0) if t1 - t0 > 0.2 else 0.0


class AcquisitionEngine:
    """Runs input streams in threads, tracks gaps and rates, and feeds subscriptions."""

    def __init__(self, streams: Sequence[InputStream], *, read_timeout_s: float = 0.05) -> None:
        channels = [stream.channel for stream in streams]
        if len(set(channels)) != len(channels):
            raise ValueError(f"every stream needs its own channel name, got {channels}")
        self.streams = list(streams)
        self.read_timeout_s = read_timeout_s
        self.start_time_utc = ""
        self._t0 = time.monotonic()
        self._lock = threading.Lock()
        self._subscriptions: list[Subscription] = []
        self._stats = {name: ChannelStats(name) for name in channels}
        self._rates = {name: _RateWindow() for name in channels}
        self._sample_channels: set[str] = set()
        self._drive: DriveSetting | None = None
        self._threads: list[threading.Thread] = []
        self._stopping = threading.Event()
        self._error: BaseException | None = None
        self._failure_callbacks: list[Callable[[BaseException], None]] = []
        self._started = False
        self._stopped = False

    # -- subscribers --------------------------------------------------------------------------

    def subscribe(
        self,
        name: str,
        *,
        max_items: int = DEFAULT_VIEW_ITEMS,
        privileged: bool = False,
        max_backlog_samples: int = DEFAULT_PRIVILEGED_BACKLOG_SAMPLES,
    ) -> Subscription:
        """A new queue of everything published from now on (subscribe before ``start``
        to miss nothing)."""
        subscription = Subscription(
            name,
            max_items=max_items,
            privileged=privileged,
            max_backlog_samples=max_backlog_samples,
        )
        with self._lock:
            self._subscriptions.append(subscription)
            if self._stopped:
                subscription.close()
        return subscription

    def unsubscribe(self, subscription: Subscription) -> None:
        """Stop feeding a subscription and close it."""
        with self._lock:
            if subscription in self._subscriptions:
                self._subscriptions.remove(subscription)
        subscription.close()

    def on_failure(self, callback: Callable[[BaseException], None]) -> None:
        """Call ``callback(error)`` once, from the failing thread, when acquisition fails."""
        with self._lock:
            self._failure_callbacks.append(callback)
            error = self._error
        if error is not None:
            callback(error)

    # -- running ------------------------------------------------------------------------------

    def host_time_s(self) -> float:
        """Seconds since the engine started (the time base of ``host_time_s`` fields)."""
        return time.monotonic() - self._t0

    def start(self) -> None:
        """Start every stream and its reader thread."""
        if self._started:
            raise RuntimeError("the acquisition engine was already started")
        self._started = True
        self._t0 = time.monotonic()
        self.start_time_utc = datetime.now(UTC).isoformat()
        for stream in self.streams:
            try:
                stream.start()
            except Exception as error:
                self.stop()
                raise AcquisitionError(f"{stream.channel}: cannot start ({error})") from error
            thread = threading.Thread(
                target=self._pump, args=(stream,), name=f"acquire:{stream.channel}", daemon=True
            )
            self._threads.append(thread)
            thread.start()

    def stop(self) -> None:
        """Stop reading, stop the streams and close every subscription (safe to call twice)."""
        if self._stopped:
            return
        self._stopping.set()
        for thread in self._threads:
            thread.join(timeout=5.0)
        for stream in self.streams:
            with contextlib.suppress(Exception):  # stopping the others matters more
                stream.stop()
        with self._lock:
            self._stopped = True
            subscriptions = list(self._subscriptions)
        for subscription in subscriptions:
            subscription.close()

    @property
    def running(self) -> bool:
        """True between ``start`` and ``stop`` while no failure occurred."""
        return self._started and not self._stopping.is_set() and self._error is None

    @property
    def error(self) -> BaseException | None:
        """The failure that ended acquisition, or None."""
        return self._error

    def raise_if_failed(self) -> None:
        """Raise the failure that ended acquisition, if any."""
        if self._error is not None:
            raise self._error

    def fail(self, error: BaseException) -> None:
        """Record a failure (the first one wins) and tell the failure callbacks."""
        with self._lock:
            if self._error is not None:
                return
            self._error = error
            callbacks = list(self._failure_callbacks)
        self._stopping.set()
        for callback in callbacks:
            callback(error)

    def _pump(self, stream: InputStream) -> None:
        """Reader thread: one stream's blocks, gap accounting, fan-out."""
        stats = self._stats[stream.channel]
        rate = self._rates[stream.channel]
        expected: int | None = None
        while not self._stopping.is_set():
            try:
                block = stream.read(self.read_timeout_s)
            except Exception as error:
                self.fail(AcquisitionError(f"{stream.channel}: read failed ({error})"))
                return
            if block is None:
                self._watch_connection(stream, stats)
                continue
            now = self.host_time_s()
            gap = None
            start = block.first_index
            if expected is None:
                if block.lost_before > 0:
                    gap = Gap(
                        block.channel, start - block.lost_before, block.lost_before, block.outage_s
                    )
            elif start > expected:
                gap = Gap(block.channel, expected, start - expected, block.outage_s)
            if stats.reconnecting or block.outage_s:
                self._back(stream, stats, block.outage_s, gap)
            with self._lock:
                if expected is not None and start < expected:
                    stats.index_regressions += 1
                expected = block.end_index
                stats.blocks += 1
                stats.end_index = block.end_index
                if isinstance(block, SampleBlock):
                    self._sample_channels.add(block.channel)
                    stats.samples_received += len(block)
                else:
                    stats.pulse = True
                    stats.samples_received += block.end_index - block.first_index
                    if block.edge_times_s.size:
                        stats.edges += int(block.edge_times_s.size)
                        recent = (*stats.last_edge_times_s, *map(float, block.edge_times_s[-2:]))
                        stats.last_edge_times_s = recent[-2:]
                if gap is not None:
                    stats.gaps += 1
                    stats.samples_lost += gap.length
                stats.sample_rate_hz = rate.add(now, block.end_index)
            if gap is not None:
                self._publish(now, gap)
            self._publish(now, block)

    def _watch_connection(self, stream: InputStream, stats: ChannelStats) -> None:
        """A stream that gives nothing: is its device away?  Say so once when it is."""
        status = stream.status()
        if status.reconnecting and not stats.reconnecting:
            with self._lock:
                stats.reconnecting = True
                stats.message = status.message
            log.warning("%s: %s", stream.channel, status.message)

    def _back(
        self, stream: InputStream, stats: ChannelStats, outage_s: float, gap: Gap | None
    ) -> None:
        """Data flow again after an outage: say how long it was and what it cost."""
        lost = 0 if gap is None else gap.length
        with self._lock:
            stats.reconnecting = False
            stats.outages += 1
            stats.message = (
                f"reconnected after {outage_s:.1f} s away; gap of {lost} samples recorded"
            )
        log.warning("%s: %s", stream.channel, stats.message)

    def _publish(self, host_time_s: float, event: Event) -> None:
        with self._lock:
            subscriptions = list(self._subscriptions)
        for subscription in subscriptions:
            if not subscription.put((host_time_s, event)):
                self.fail(
                    SubscriberOverrunError(
                        f"subscriber {subscription.name!r} fell behind by more than "
                        f"{subscription.max_backlog_samples} samples (storage too slow?); "
                        "acquisition stopped so that no sample is silently lost"
                    )
                )

    # -- what procedures add ------------------------------------------------------------------

    def note_drive(
        self, frequency_hz: float, amplitude_m: float, enabled: bool, source: int = COMMANDED
    ) -> DriveSetting:
        """Publish a drive setting (commanded or read back) stamped with time and sample index."""
        setting = DriveSetting(
            host_time_s=self.host_time_s(),
            sample_index=self.latest_index or 0,
            frequency_hz=float(frequency_hz),
            amplitude_m=float(amplitude_m),
            enabled=bool(enabled),
            source=source,
        )
        with self._lock:
            self._drive = setting
        self._publish(setting.host_time_s, setting)
        return setting

    def mark_step(self, mark: StepMark | StepBegun) -> None:
        """Publish a sweep step mark (when the step ends) or the news that one has begun."""
        self._publish(self.host_time_s(), mark)

    def publish(self, event: DriveSetting | StepMark) -> None:
        """Publish a drive setting or step mark as it is (e.g. replayed from a recording)."""
        if isinstance(event, DriveSetting):
            with self._lock:
                self._drive = event
        self._publish(self.host_time_s(), event)

    # -- live quantities ----------------------------------------------------------------------

    @property
    def latest_index(self) -> int | None:
        """One past the newest sample index received on any sampled channel."""
        with self._lock:
            ends = [self._stats[c].end_index for c in self._sample_channels]
        ends = [e for e in ends if e is not None]
        return max(ends) if ends else None

    @property
    def aligned_end_index(self) -> int | None:
        """One past the newest index that every sampled channel has received."""
        with self._lock:
            ends = [self._stats[c].end_index for c in self._sample_channels]
        if not ends or any(e is None for e in ends):
            return None
        return min(ends)

    def stats(self) -> EngineStats:
        """A snapshot of rates, losses, drive setting and per-subscriber drops."""
        with self._lock:
            channels = {name: ChannelStats(**vars(stats)) for name, stats in self._stats.items()}
            subscribers = tuple(
                SubscriberStats(
                    s.name, s.privileged, s.dropped_items, s.dropped_samples, s.backlog_items
                )
                for s in self._subscriptions
            )
            drive = self._drive
            error = self._error
        return EngineStats(
            host_time_s=self.host_time_s(),
            channels=channels,
            subscribers=subscribers,
            drive=drive,
            latest_index=self.latest_index,
            aligned_end_index=self.aligned_end_index,
            error="" if error is None else str(error),
        )
