"""The DAQ board as a device: declared once, its transport a backend passed in.

A :class:`DaqBoard` owns one stream from one board (serial, or an in-process
simulation: anything implementing :class:`DaqBackend`).  It checks the board's
identity, validates the configuration against the limits the board reports,
counts gaps in the running sample index exactly, and fans the samples out to the
role drivers (angle sensor, laser, tachometer, see :mod:`drivers.sensors`) that
share the stream.  Samples are never invented: a gap is reported as a gap.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

import numpy as np

from drivers.daq_protocol import BoardConfiguration, BoardIdentity
from drivers.interfaces import DeviceError, LimitError, StreamStatus, WrongDeviceError

DEFAULT_MODEL = "IRDAQ-4"


@dataclass(frozen=True)
class RawChunk:
    """Consecutive samples from the board, as counts, with their running index."""

    first_index: int
    analog: np.ndarray  # (samples, configured channels) int16 counts
    digital: np.ndarray  # (samples,) uint16 digital lines, bit 0 = tachometer
    # the board was away (disconnected, then reconnected) this long just before these
    # samples; the samples lost before them are then estimated from it (DaqBoard)
    outage_s: float = 0.0

    @property
    def n_samples(self) -> int:
        """Samples in the chunk."""
        return int(self.digital.shape[0])

    @property
    def end_index(self) -> int:
        """Running index one past the last sample."""
        return self.first_index + self.n_samples


@runtime_checkable
class DaqBackend(Protocol):
    """How a :class:`DaqBoard` talks to its board; serial and simulated backends implement it.

    ``read_chunk`` is called from one thread only, the board's reader; it returns
    chunks in index order (dropping anything that would go backwards) and raises
    :class:`DeviceError` when the device is gone.
    """

    @property
    def description(self) -> str:
        """Where the board is, for messages: e.g. ``'serial port /dev/ttyACM0'``."""
        ...

    @property
    def frames_rejected(self) -> int:
        """Frames discarded so far for a bad CRC or framing (their samples show as gaps)."""
        ...

    def connect(self) -> BoardIdentity:
        """Reach the board, stop a stream left running, and return what ``IDN?`` says."""
        ...

    def configure(self, sample_rate_hz: float, channels: tuple[int, ...]) -> BoardConfiguration:
        """``CONF``: returns the rate the board really runs and its frame size."""
        ...

    def start(self) -> None:
        """``START``: a new stream whose running index begins at 0."""
        ...

    def read_chunk(self, timeout_s: float) -> RawChunk | None:
        """The next samples in index order, or None when none came within ``timeout_s``."""
        ...

    def stop(self) -> None:
        """``STOP`` the stream (the connection stays open)."""
        ...

    def close(self) -> None:
        """Release the transport; safe to call more than once."""
        ...


class BoardRole(Protocol):
    """A role driver that takes its samples from a :class:`DaqBoard` (see drivers.sensors)."""

    def attach(self, *, start: bool = True) -> None:
        """Subscribe to the board's stream, starting it if ``start`` and not yet running."""
        ...


class RoleQueue:
    """One role's queue of chunks from the board (bounded: an unread role cannot eat the memory)."""

    def __init__(self, max_samples: int, wait_when_full: bool, stopping: threading.Event) -> None:
        self.max_samples = max_samples
        self.wait_when_full = wait_when_full
        self.stopping = stopping
        self.closed = False  # its role left: nothing waits for it any more
        self.chunks: deque[tuple[RawChunk, int]] = deque()
        self.queued_samples = 0
        self.samples_received = 0
        self.samples_lost = 0
        self.condition = threading.Condition()

    def push(self, chunk: RawChunk, lost_before: int) -> None:
        """Queue a chunk (the reader thread); when full, wait or drop the oldest, as configured."""
        with self.condition:
            if self.wait_when_full:
                # Back-pressure until the chunk fits (an empty queue takes any chunk): the
                # device drops, and says so.  Nothing is dropped here.
                while (
                    self.queued_samples
                    and self.queued_samples + chunk.n_samples > self.max_samples
                    and not self.stopping.is_set()
                    and not self.closed
                ):
                    self.condition.wait(0.05)
            self.chunks.append((chunk, lost_before))
            self.queued_samples += chunk.n_samples
            self.samples_lost += lost_before
            while (
                not self.wait_when_full
                and self.queued_samples > self.max_samples
                and len(self.chunks) > 1
            ):
                # The role is not being read: drop its oldest samples, and say so.
                dropped, lost = self.chunks.popleft()
                self.queued_samples -= dropped.n_samples
                self.samples_lost += dropped.n_samples
                head, head_lost = self.chunks.popleft()
                if dropped.outage_s and not head.outage_s:  # the outage stays marked
                    head = replace(head, outage_s=dropped.outage_s)
                self.chunks.appendleft((head, head_lost + lost + dropped.n_samples))
            self.condition.notify_all()

    def take(self, timeout_s: float, board: DaqBoard) -> tuple[RawChunk, int] | None:
        """Everything queued and contiguous, merged into one chunk, with its gap before."""
        deadline = time.monotonic() + timeout_s
        with self.condition:
            while not self.chunks:
                if board.failure:
                    raise DeviceError(board.failure)
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self.condition.wait(min(remaining, 0.05))
            chunk, lost = self.chunks.popleft()
            parts = [chunk]
            while self.chunks and self.chunks[0][1] == 0:
                parts.append(self.chunks.popleft()[0])
            self.queued_samples -= sum(p.n_samples for p in parts)
            self.condition.notify_all()  # room again for a reader waiting on a full queue
        if len(parts) > 1:
            chunk = RawChunk(
                parts[0].first_index,
                np.concatenate([p.analog for p in parts]),
                np.concatenate([p.digital for p in parts]),
                parts[0].outage_s,
            )
        self.samples_received += chunk.n_samples
        return chunk, lost


class DaqBoard:
    """One DAQ board and its single stream, shared by the role drivers attached to it.

    Each role queues up to ``role_buffer_s`` of samples.  When a role's queue is
    full, ``when_role_full='drop'`` (the default, right for hardware: one idle role
    must not stall the others) drops that role's oldest samples and reports them
    lost; ``'wait'`` holds the reader back instead, so the device side drops (and
    the index gap says how many) or, for a simulation run as fast as possible,
    simply waits: nothing is lost.

    When the board goes away while streaming (a USB cable knocked, a board reset: the
    port fails), ``reconnect_for_s > 0`` keeps the stream alive: the board is
    ``reconnecting`` (status says so, role reads return nothing) while the port is
    reopened every ``reconnect_interval_s``; once the same board answers (same identity,
    same rate) it is configured and started again, and its new stream (which counts
    from 0) continues the running index after a gap as long as the outage (outage time
    x sample rate, an estimate: the board restarted its count).  The first chunk after
    it carries ``outage_s``.  A different board there, or no board within
    ``reconnect_for_s``, fails the stream as an unplugged board without reconnection does.
    """

    def __init__(
        self,
        backend: DaqBackend,
        *,
        sample_rate_hz: float,
        analog_channels: tuple[int, ...],
        expected_model: str = DEFAULT_MODEL,
        stall_timeout_s: float = 1.0,
        role_buffer_s: float = 10.0,
        when_role_full: str = "drop",
        reconnect_for_s: float = 0.0,
        reconnect_interval_s: float = 0.5,
    ) -> None:
        if not (math.isfinite(reconnect_for_s) and reconnect_for_s >= 0):
            raise LimitError(f"reconnect_for_s={reconnect_for_s} must be 0 (never) or more")
        if not (math.isfinite(reconnect_interval_s) and reconnect_interval_s > 0):
            raise LimitError(f"reconnect_interval_s={reconnect_interval_s} must be positive")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise LimitError(f"sample_rate_hz={sample_rate_hz} must be a positive number")
        channels = tuple(int(c) for c in analog_channels)
        if not channels:
            raise LimitError("analog_channels is empty: enable at least one analog input")
        if len(set(channels)) != len(channels):
            raise LimitError(f"analog_channels={analog_channels} names a channel twice")
        if any(c < 0 for c in channels):
            raise LimitError(f"analog_channels={analog_channels}: channels are numbered from 0")
        if when_role_full not in ("drop", "wait"):
            raise LimitError(f"when_role_full={when_role_full!r} must be 'drop' or 'wait'")
        self.backend = backend
        self.requested_rate_hz = float(sample_rate_hz)
        self.analog_channels = tuple(sorted(channels))
        self.expected_model = expected_model
        self.stall_timeout_s = stall_timeout_s
        self.role_buffer_s = role_buffer_s
        self.when_role_full = when_role_full
        self.reconnect_for_s = float(reconnect_for_s)
        self.reconnect_interval_s = float(reconnect_interval_s)
        self.reconnecting = False  # the board went away; the reader is trying to reach it again
        self.reconnections = 0
        self.identity: BoardIdentity | None = None
        self.configuration: BoardConfiguration | None = None
        self.failure = ""  # set when the device went away; role reads then raise
        self._lock = threading.Lock()
        self._open_lock = threading.Lock()
        self._subscriptions: tuple[RoleQueue, ...] = ()  # replaced whole: the reader
        # thread reads it without the lock, which stop() holds while joining that thread
        self._thread: threading.Thread | None = None
        self._stop_reading = threading.Event()
        self._streaming = False
        self._expected_index = 0
        self._samples_received = 0
        self._samples_lost = 0
        self._last_data = 0.0
        self._message = ""
        self._index_offset = 0  # running index of the current connection's sample 0
        self._outage_s = 0.0  # the outage to mark on the next chunk

    # --- set-up ---------------------------------------------------------------------------
    def open(self) -> BoardIdentity:
        """Connect, check it is the expected board, and configure it (validated first)."""
        with self._open_lock:  # roles may start from several threads at once
            return self._open_locked()

    def _open_locked(self) -> BoardIdentity:
        if self.identity is not None:
            return self.identity
        identity = self.backend.connect()
        try:
            if identity.model != self.expected_model:
                raise WrongDeviceError(
                    f"{self.backend.description} is a {identity.model!r} "
                    f"(serial {identity.serial}), expected a {self.expected_model!r} DAQ board"
                )
            self._validate_against(identity)
            self.configuration = self.backend.configure(
                self.requested_rate_hz, self.analog_channels
            )
        except (DeviceError, LimitError):
            self.backend.close()  # refused or failed: the port is not left open
            raise
        self.identity = identity
        return identity

    def _validate_against(self, identity: BoardIdentity) -> None:
        low, high = identity.min_rate_hz, identity.max_rate_hz
        if not low <= self.requested_rate_hz <= high:
            raise LimitError(
                f"sample_rate_hz={self.requested_rate_hz:g} is outside the range "
                f"{low:g}..{high:g} Hz of {identity.model} on {self.backend.description}"
            )
        unknown = [c for c in self.analog_channels if c >= identity.channels]
        if unknown:
            raise LimitError(
                f"analog channel {unknown[0]} does not exist: {identity.model} has "
                f"channels 0..{identity.channels - 1}"
            )

    @property
    def sample_rate_hz(self) -> float:
        """The rate the board really runs (its clock divides); the requested one before open()."""
        if self.configuration is None:
            return self.requested_rate_hz
        return self.configuration.sample_rate_hz

    @property
    def volts_per_count(self) -> float:
        """ADC scale reported by the board: counts span -range_v..+range_v."""
        if self.identity is None:
            raise DeviceError("the DAQ board is not open yet: call open() or start a role")
        return self.identity.range_v / (1 << (self.identity.adc_bits - 1))

    @property
    def adc_limits(self) -> tuple[int, int]:
        """Lowest and highest count the ADC can give (readings at a rail are saturated)."""
        if self.identity is None:
            raise DeviceError("the DAQ board is not open yet: call open() or start a role")
        half = 1 << (self.identity.adc_bits - 1)
        return -half, half - 1

    def column_of(self, channel: int) -> int:
        """Where an analog channel sits in a chunk; a clear error if it is not enabled."""
        if channel not in self.analog_channels:
            raise LimitError(
                f"analog channel {channel} is not enabled on this board "
                f"(enabled: {', '.join(map(str, self.analog_channels))})"
            )
        return self.analog_channels.index(channel)

    # --- streaming ------------------------------------------------------------------------
    def subscribe(self, *, start: bool = True) -> RoleQueue:
        """A queue that receives every chunk from now on; starts the stream if asked and needed."""
        self.open()
        subscription = RoleQueue(
            max(1, int(self.role_buffer_s * self.sample_rate_hz)),
            wait_when_full=self.when_role_full == "wait",
            stopping=self._stop_reading,
        )
        with self._lock:
            self._subscriptions = (*self._subscriptions, subscription)
            if start and not self._streaming:
                self._start_locked()
        return subscription

    def start_roles(self, *roles: BoardRole) -> None:
        """Start several roles on one stream so that all of them begin at sample index 0.

        (Starting roles one by one also works; a role started while the board
        already streams begins at the next chunk.)
        """
        for role in roles:
            role.attach(start=False)
        with self._lock:
            if not self._streaming:
                self._start_locked()

    def unsubscribe(self, subscription: RoleQueue) -> None:
        """Stop feeding a role; the stream stops when the last role leaves."""
        with subscription.condition:
            subscription.closed = True
            subscription.condition.notify_all()
        with self._lock:
            self._subscriptions = tuple(s for s in self._subscriptions if s is not subscription)
            if not self._subscriptions and self._streaming:
                self._stop_locked()

    def _start_locked(self) -> None:
        self.failure = ""
        self._message = ""
        self._expected_index = 0
        self._index_offset = 0
        self._outage_s = 0.0
        self.reconnecting = False
        self.backend.start()
        self._streaming = True
        self._last_data = time.monotonic()
        self._stop_reading.clear()
        self._thread = threading.Thread(target=self._read_loop, name="daq-reader", daemon=True)
        self._thread.start()

    def _stop_locked(self) -> None:
        self._streaming = False
        try:
            if not self.failure and not self.reconnecting:  # the reader owns a reconnecting port
                self.backend.stop()
        finally:
            self._stop_reading.set()
            if self._thread is not None:
                self._thread.join(timeout=5)
            self._thread = None

    def close(self) -> None:
        """Stop streaming and release the transport; safe to call more than once."""
        with self._lock:
            self._subscriptions = ()
            if self._streaming:
                with contextlib.suppress(DeviceError):
                    self._stop_locked()
        self.backend.close()
        self.identity = None

    def __enter__(self) -> DaqBoard:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _read_loop(self) -> None:
        while not self._stop_reading.is_set():
            try:
                chunk = self.backend.read_chunk(0.05)
            except DeviceError as error:
                if self._reconnect(str(error)):
                    continue
                return
            now = time.monotonic()
            if chunk is None:
                silent = now - self._last_data
                if self._streaming and silent > self.stall_timeout_s:
                    self._message = (
                        f"no data from the DAQ board on {self.backend.description} "
                        f"for {silent:.1f} s (stalled?)"
                    )
                continue
            self._last_data = now
            if self._index_offset or self._outage_s:
                chunk = RawChunk(
                    chunk.first_index + self._index_offset,
                    chunk.analog,
                    chunk.digital,
                    self._outage_s,
                )
                self._outage_s = 0.0
            if self._message.startswith("no data"):
                self._message = ""
            self._deliver(chunk)

    def _deliver(self, chunk: RawChunk) -> None:
        lost = chunk.first_index - self._expected_index
        if lost < 0:  # backends never go backwards; guard so we can never double-count
            return
        if lost:
            self._message = f"lost {lost} samples before index {chunk.first_index}"
            if chunk.outage_s:
                self._message += f" (the board was away for {chunk.outage_s:.1f} s)"
        self._samples_lost += lost
        self._samples_received += chunk.n_samples
        self._expected_index = chunk.end_index
        chunk.analog.setflags(write=False)  # shared by every role: nobody may edit it
        chunk.digital.setflags(write=False)
        for subscription in self._subscriptions:
            subscription.push(chunk, lost)

    def _reconnect(self, reason: str) -> bool:
        """The board went away: reach it again (True), or fail the stream (False).

        Runs in the reader thread, which alone touches the backend meanwhile (``stop``
        does not, while ``reconnecting``).
        """
        if self.reconnect_for_s <= 0 or self.identity is None or self.configuration is None:
            self._fail(reason)
            return False
        self.reconnecting = True
        self._message = f"{reason}; reconnecting"
        deadline = time.monotonic() + self.reconnect_for_s
        while not self._stop_reading.is_set():
            self.backend.close()
            try:
                started = self._restart_stream()
            except _DifferentBoardError as error:
                self._fail(str(error))
                return False
            except DeviceError as error:
                if time.monotonic() >= deadline:
                    self._fail(
                        f"{reason}; no board answered within {self.reconnect_for_s:g} s "
                        f"(last try: {error})"
                    )
                    return False
                self._message = f"{reason}; reconnecting (last try: {error})"
                self._stop_reading.wait(self.reconnect_interval_s)
                continue
            if self._stop_reading.is_set():  # stopped while we reconnected: leave it stopped
                with contextlib.suppress(DeviceError):
                    self.backend.stop()
                return False
            outage_s = max(0.0, started - self._last_data)
            self._index_offset = self._expected_index + round(outage_s * self.sample_rate_hz)
            self._outage_s = outage_s
            self._last_data = time.monotonic()
            self.reconnections += 1
            self.reconnecting = False
            self._message = (
                f"the DAQ board on {self.backend.description} is back after {outage_s:.1f} s"
            )
            return True
        return False

    def _restart_stream(self) -> float:
        """Connect, check it is the same board at the same rate, START; the host time of START."""
        identity = self.backend.connect()
        if identity != self.identity:
            self.backend.close()
            raise _DifferentBoardError(
                f"a different board answered on {self.backend.description} after it went away "
                f"({identity.model} serial {identity.serial}, was {self.identity.model} serial "
                f"{self.identity.serial}): the stream stops rather than mix two boards"
            )
        configuration = self.backend.configure(self.requested_rate_hz, self.analog_channels)
        if configuration != self.configuration:
            self.backend.close()
            raise _DifferentBoardError(
                f"the DAQ board on {self.backend.description} came back configured as "
                f"{configuration}, not {self.configuration}: the stream stops"
            )
        started = time.monotonic()
        self.backend.start()
        return started

    def _fail(self, message: str) -> None:
        self.failure = message
        self._message = message
        for subscription in self._subscriptions:
            with subscription.condition:
                subscription.condition.notify_all()

    def status(self) -> StreamStatus:
        """Health of the board's stream as a whole."""
        return StreamStatus(
            running=self._streaming and not self.failure,
            samples_received=self._samples_received,
            samples_lost=self._samples_lost,
            frames_rejected=self.backend.frames_rejected,
            message=self._message,
            reconnecting=self.reconnecting and not self.failure,
        )


class _DifferentBoardError(DeviceError):
    """Something other than the board that went away answered in its place."""
