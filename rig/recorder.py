"""Crash-safe HDF5 recorder: engine events appended to a SWMR file, flushed at least every second.

The layout is documented in docs/recording_layout.md.  Events are buffered in memory
and written in one append per dataset at each flush, which keeps the cost per block
small at high sample rates; the file is readable (SWMR) while it is written and
holds everything up to the last flush if the process dies.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from analysis.output_paths import HDF5_SUFFIXES, OutputPathError, check_suffix
from analysis.progress import ProgressText
from drivers.interfaces import PulseBlock, SampleBlock
from drivers.sensors import FLAG_NOT_FINITE
from recording.layout import (
    FORMAT_NAME,
    FORMAT_VERSION,
    OUTAGE_CHANNEL_BYTES,
    ChannelSpec,
    RecordingStatus,
    chunk_length,
)
from recording.metadata import RecordingMetadata
from recording.writer import RecordingWriter
from rig.events import DriveSetting, Event, Gap, StepBegun, StepMark

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "ChannelSpec",
    "DiskFullError",
    "Recorder",
    "RecorderThread",
    "RecordingError",
    "RecordingExistsError",
    "RecordingMetadata",
    "attach_recorder",
    "check_destination",
    "software_version",
]

DEFAULT_FLUSH_INTERVAL_S = 0.5
MAX_FLUSH_INTERVAL_S = 1.0
DISK_RESERVE_BYTES = 1 << 20  # kept free besides what the next flush may need
RECORDER_NICENESS = 5  # the writer thread runs this much "nicer" than acquisition


class RecordingError(RuntimeError):
    """The recording cannot be created or written; the message names the file and the cause."""


class RecordingExistsError(RecordingError):
    """The output file exists and overwriting was not asked for."""


class DiskFullError(RecordingError):
    """The disk is (almost) full: recording stopped before a write could fail half-way."""


def software_version() -> str:
    """The installed impact-rig version (or 'unknown' when running from an uninstalled tree)."""
    try:
        return version("impact-rig")
    except PackageNotFoundError:
        return "unknown"


def check_destination(
    path: str | Path, *, overwrite: bool = False, min_free_bytes: int = 0
) -> Path:
    """Refuse, before anything starts, a path that exists, cannot be written or has no room."""
    path = Path(path)
    if path.is_dir():
        raise RecordingError(f"{path}: is a folder; give a file name such as {path / 'run.h5'}")
    try:
        check_suffix(path, HDF5_SUFFIXES, "a recording (HDF5)")
    except OutputPathError as error:
        raise RecordingError(str(error)) from None
    if path.exists() and not overwrite:
        raise RecordingExistsError(
            f"{path}: already exists; choose another name or pass --overwrite to replace it"
        )
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise RecordingError(f"{path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise RecordingError(f"{path}: folder {folder} is not writable")
    free = shutil.disk_usage(folder).free
    if free < min_free_bytes:
        raise RecordingError(
            f"{path}: only {free / 1e6:.1f} MB free in {folder}; this run needs about "
            f"{min_free_bytes / 1e6:.1f} MB"
        )
    return path


class _ChannelBuffer:
    """Events of one channel waiting for the next flush."""

    def __init__(self, spec: ChannelSpec) -> None:
        self.spec = spec
        self.raw: list[np.ndarray] = []
        self.values: list[np.ndarray] = []
        self.flags: list[np.ndarray] = []
        self.edges: list[np.ndarray] = []
        self.edge_times: list[np.ndarray] = []
        self.blocks: list[tuple] = []
        self.gaps: list[tuple] = []
        self.stored = 0  # samples (or edges) stored or pending
        self.lost = 0

    def clear(self) -> None:
        for pending in (
            self.raw,
            self.values,
            self.flags,
            self.edges,
            self.edge_times,
            self.blocks,
            self.gaps,
        ):
            pending.clear()


class Recorder:
    """Writes one recording, from one thread (``RecorderThread`` does that for the engine)."""

    def __init__(
        self,
        path: str | Path,
        channels: list[ChannelSpec],
        metadata: RecordingMetadata,
        *,
        overwrite: bool = False,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
        compression: str | None = "auto",
        min_free_bytes: int = 0,
    ) -> None:
        if not 0 < flush_interval_s <= MAX_FLUSH_INTERVAL_S:
            raise ValueError(
                f"flush_interval_s is {flush_interval_s}; expected a value in (0, "
                f"{MAX_FLUSH_INTERVAL_S}] so that a crash loses at most a second"
            )
        names = [spec.name for spec in channels]
        if len(set(names)) != len(names):
            raise ValueError(f"channel names must be unique, got {names}")
        self.path = check_destination(path, overwrite=overwrite, min_free_bytes=min_free_bytes)
        self.flush_interval_s = flush_interval_s
        self._buffers = {spec.name: _ChannelBuffer(spec) for spec in channels}
        self._records_samples = any(spec.kind == "samples" for spec in channels)
        self._first_sample_index: int | None = None
        self._pulses_before_samples: list[tuple[PulseBlock, float]] = []
        self._drive: list[tuple] = []
        self._steps: list[tuple] = []
        self._outages: list[tuple] = []
        self._last_host_time_s = 0.0
        self._flushes = 0
        self._last_flush = time.monotonic()
        self._failed: RecordingError | None = None
        self._closed = False
        self._chunk_bytes = sum(
            chunk_length(spec.sample_rate_hz) * (5 + np.dtype(spec.raw_dtype).itemsize)
            for spec in channels
        )
        if overwrite and self.path.exists():
            self.path.unlink()
        meta = metadata
        if not meta.start_time_utc:
            meta = replace(meta, start_time_utc=datetime.now(UTC).isoformat())
        try:
            self._file = RecordingWriter(
                self.path,
                channels,
                meta,
                software_version=software_version(),
                compression=compression,
            )
        except FileExistsError:
            raise RecordingExistsError(
                f"{self.path}: already exists; choose another name or pass --overwrite"
            ) from None
        except (OSError, ValueError) as error:
            raise RecordingError(f"{self.path}: cannot set up the file ({error})") from None
        try:
            self._write_status(closed=False, reason="recording")
            self._file.flush()
        except (OSError, ValueError) as error:
            self._abandon()
            with contextlib.suppress(OSError):
                self.path.unlink()
            raise RecordingError(f"{self.path}: cannot set up the file ({error})") from None

    # -- writing ------------------------------------------------------------------------------

    @property
    def samples_written(self) -> int:
        """Samples of all sampled channels stored or waiting for the next flush."""
        return sum(b.stored for b in self._buffers.values() if b.spec.kind == "samples")

    @property
    def samples_lost(self) -> int:
        """Samples recorded as gaps by the sampled channels (a pulse stream's gaps are the same
        board samples again, and are in its own gaps table)."""
        return sum(b.lost for b in self._buffers.values() if b.spec.kind == "samples")

    @property
    def flush_due(self) -> bool:
        """True when the flush interval has passed since the last flush."""
        return time.monotonic() - self._last_flush >= self.flush_interval_s

    def add(self, event: Event, host_time_s: float) -> None:
        """Queue one engine event for the next flush (blocks of unknown channels are an error).

        After the disk filled, drive settings and step marks (a few bytes, written into the
        reserve at close) are still taken, so the file tells how the run ended.
        """
        if isinstance(self._failed, DiskFullError):
            if isinstance(event, DriveSetting | StepMark) and not self._closed:
                self._add_annotation(event)
            return
        self._check_usable()
        self._last_host_time_s = max(self._last_host_time_s, host_time_s)
        if isinstance(event, SampleBlock):
            buffer = self._channel(event.channel, "samples")
            if not (math.isfinite(event.timestamp_s) and event.timestamp_s >= 0):
                raise RecordingError(
                    f"{self.path}: channel {event.channel!r}: block at sample "
                    f"{event.first_index} has timestamp {event.timestamp_s!r}; expected a "
                    "finite device time >= 0"
                )
            n = len(event)
            flags = np.zeros(n, "u1") if event.flags is None else np.asarray(event.flags, "u1")
            if flags.shape != (n,):
                raise ValueError(f"channel {event.channel!r}: {flags.size} flags for {n} samples")
            values = np.asarray(event.values, dtype="<f4")
            finite = np.isfinite(values)
            if not finite.all():  # an inf or NaN is kept as read, but never marked good
                flags = flags | np.where(finite, 0, FLAG_NOT_FINITE).astype("u1")
            buffer.raw.append(np.asarray(event.raw))
            buffer.values.append(values)
            buffer.flags.append(flags)
            buffer.blocks.append(
                (
                    event.first_index,
                    n,
                    buffer.stored,
                    event.timestamp_s,
                    host_time_s,
                    event.lost_before,
                )
            )
            buffer.stored += n
            if self._first_sample_index is None:
                self._first_sample_index = event.first_index
                self._release_waiting_pulses()
        elif isinstance(event, PulseBlock):
            self._channel(event.channel, "pulses")
            if self._records_samples and self._first_sample_index is None:
                self._pulses_before_samples.append((event, host_time_s))
            else:
                self._add_pulses(event, host_time_s)
        elif isinstance(event, Gap):
            buffer = self._channel(event.channel, None)
            buffer.gaps.append((event.start_index, event.length))
            buffer.lost += event.length
            if event.outage_s > 0:
                name = event.channel.encode("utf-8")[:OUTAGE_CHANNEL_BYTES]
                self._outages.append(
                    (name, event.start_index, event.length, event.outage_s, host_time_s)
                )
        elif isinstance(event, DriveSetting | StepMark):
            self._add_annotation(event)
        elif not isinstance(event, StepBegun):  # the step's StepMark, at its end, says it all
            raise TypeError(f"cannot record {type(event).__name__}")

    def _add_pulses(self, event: PulseBlock, host_time_s: float) -> None:
        """Queue a block of edges, less any edge before the recording's first sample.

        A recorder attached to a running engine gets each stream from that stream's next
        block, so a pulse block can begin before the first sample recorded; its earlier
        edges belong to no recorded sample and are dropped, so that every channel of the
        file starts at one sample index.
        """
        start = self._first_sample_index
        if start is not None and event.first_index < start:
            if event.end_index <= start:
                return
            kept = np.asarray(event.edge_indices) >= start
            event = replace(
                event,
                first_index=start,
                edge_indices=np.asarray(event.edge_indices)[kept],
                edge_times_s=np.asarray(event.edge_times_s)[kept],
                lost_before=0,
            )
        buffer = self._channel(event.channel, "pulses")
        edges = np.asarray(event.edge_indices, dtype="<i8")
        buffer.edges.append(edges)
        buffer.edge_times.append(np.asarray(event.edge_times_s, dtype="<f8"))
        buffer.blocks.append(
            (event.first_index, event.end_index, host_time_s, event.lost_before, edges.size)
        )
        buffer.stored += edges.size

    def _release_waiting_pulses(self) -> None:
        """Queue the pulse blocks held until the first sample's index was known."""
        waiting, self._pulses_before_samples = self._pulses_before_samples, []
        for event, host_time_s in waiting:
            self._add_pulses(event, host_time_s)

    def _add_annotation(self, event: DriveSetting | StepMark) -> None:
        if isinstance(event, DriveSetting):
            self._drive.append(
                (
                    event.host_time_s,
                    event.sample_index,
                    event.frequency_hz,
                    event.amplitude_m,
                    int(event.enabled),
                    event.source,
                )
            )
        elif isinstance(event, StepMark):
            self._steps.append(
                (
                    event.step,
                    event.direction,
                    event.frequency_hz,
                    event.amplitude_m,
                    event.settle_start_index,
                    event.dwell_start_index,
                    event.dwell_end_index,
                    int(event.complete),
                )
            )
        else:
            raise TypeError(f"cannot record {type(event).__name__}")

    def _channel(self, name: str, kind: str | None) -> _ChannelBuffer:
        buffer = self._buffers.get(name)
        if buffer is None:
            raise RecordingError(
                f"{self.path}: a block of channel {name!r} arrived, but the recording was set up "
                f"for {sorted(self._buffers)}"
            )
        if kind is not None and buffer.spec.kind != kind:
            raise RecordingError(
                f"{self.path}: channel {name!r} was declared as {buffer.spec.kind} but sent {kind}"
            )
        return buffer

    @property
    def error(self) -> RecordingError | None:
        """The failure that stopped the recording, or None."""
        return self._failed

    def _pending_bytes(self) -> int:
        total = 0
        for buffer in self._buffers.values():
            total += sum(a.nbytes for a in buffer.raw) + sum(a.nbytes for a in buffer.values)
            total += sum(a.nbytes for a in buffer.edges) * 2 + 64 * len(buffer.blocks)
        return total + 64 * (len(self._drive) + len(self._steps)) + 96 * len(self._outages)

    def _check_room(self) -> None:
        """Stop cleanly while there is still room, rather than let HDF5 fail mid-write."""
        need = 2 * self._pending_bytes() + self._chunk_bytes + DISK_RESERVE_BYTES
        free = shutil.disk_usage(self.path.parent).free
        if free < need:
            self._failed = DiskFullError(
                f"{self.path}: disk almost full ({free / 1e6:.2f} MB free, the next write needs "
                f"about {need / 1e6:.2f} MB); recording stopped, the data recorded so far "
                "are kept"
            )
            raise self._failed

    def flush(self) -> None:
        """Append everything pending and flush the file, so a reader (or a crash) sees it."""
        self._check_usable()
        self._check_room()
        try:
            for buffer in self._buffers.values():
                self._write_channel(buffer)
            self._file.append_drive(self._drive)
            self._file.append_steps(self._steps)
            self._file.append_outages(self._outages)
            self._drive.clear()
            self._steps.clear()
            self._outages.clear()
            self._flushes += 1
            self._write_status(closed=False, reason="recording")
            self._file.flush()
        except (OSError, ValueError, RuntimeError) as error:
            self._failed = RecordingError(
                f"{self.path}: writing failed ({_plain(error)}); the data flushed before "
                f"(up to {self._last_flush_age():.1f} s ago) stay readable"
            )
            raise self._failed from None
        self._last_flush = time.monotonic()

    def _write_channel(self, buffer: _ChannelBuffer) -> None:
        columns = {"raw": buffer.raw, "values": buffer.values, "flags": buffer.flags} \
            if buffer.spec.kind == "samples" else \
            {"edge_indices": buffer.edges, "edge_times_s": buffer.edge_times}
        self._file.append_channel(buffer.spec.name, columns, buffer.blocks, buffer.gaps)
        buffer.clear()

    def _write_status(self, *, closed: bool, reason: str) -> None:
        self._file.write_status(
            RecordingStatus(
                end_host_time_s=self._last_host_time_s,
                samples_written=self.samples_written,
                samples_lost=self.samples_lost,
                flushes=self._flushes,
                closed=closed,
                stop_reason=reason,
            )
        )

    def close(self, stop_reason: str = "completed") -> None:
        """Flush what is pending, mark the file closed with ``stop_reason`` and release it.

        After a failure already reported (``error``) nothing more is appended: a full
        disk still gets its status row (closed, with the reason); after a write error
        the file is released as it is (what was flushed before stays readable).
        Raises only for a new failure while closing.
        """
        if self._closed:
            return
        if isinstance(self._failed, DiskFullError):
            self._close_after_disk_full()
            return
        if self._failed is not None:
            self._abandon()
            return
        self._release_waiting_pulses()  # no sample ever came: the edges are all there is
        try:
            self.flush()
            self._write_status(closed=True, reason=stop_reason)
            self._file.flush()
        except DiskFullError:  # the disk filled since the last flush: still say so in the file
            self._close_after_disk_full()
            raise
        except RecordingError:
            self._abandon()
            raise
        except (OSError, ValueError, RuntimeError) as error:
            self._abandon()
            raise RecordingError(f"{self.path}: closing failed ({_plain(error)})") from None
        self._file.close()
        self._closed = True

    def _close_after_disk_full(self) -> None:
        """Write the drive settings, step marks and closed status (a few bytes, into the
        reserve kept free), then release the file; the pending samples are not written."""
        for buffer in self._buffers.values():  # so that samples_written tells what the file has
            pending = buffer.raw if buffer.spec.kind == "samples" else buffer.edges
            buffer.stored -= sum(len(part) for part in pending)
            buffer.clear()
        try:
            self._file.append_drive(self._drive)
            self._file.append_steps(self._steps)
            self._file.append_outages(self._outages)
            self._write_status(closed=True, reason=str(self._failed))
            self._file.flush()
            self._file.close()
        except (OSError, ValueError, RuntimeError):
            self._abandon()
        self._closed = True

    def _abandon(self) -> None:
        """Release the file after a failure without raising a second error."""
        self._closed = True
        with contextlib.suppress(Exception):  # the first error is the one worth reporting
            self._file.close()

    def _check_usable(self) -> None:
        if self._failed is not None:
            raise self._failed
        if self._closed:
            raise RecordingError(f"{self.path}: the recording is closed")

    def _last_flush_age(self) -> float:
        return time.monotonic() - self._last_flush

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.close()
        elif not self._closed:
            reason = "interrupted" if issubclass(kind, KeyboardInterrupt) else f"error: {value}"
            with contextlib.suppress(RecordingError):  # the propagating exception says why
                self.close(reason)


def _plain(error: BaseException) -> str:
    text = str(error)
    if isinstance(error, OSError) and error.errno is not None:
        text = f"{os.strerror(error.errno)}: {text}"
    return text


class EventSource(Protocol):
    """What the recorder thread drains: a subscription of the acquisition engine."""

    @property
    def closed(self) -> bool: ...

    def get_many(self, timeout_s: float = 0.1) -> list[tuple[float, Event]]: ...


def _lower_this_threads_priority(niceness: int) -> None:
    """Make the calling thread yield the CPU to the acquisition threads when cores are busy.

    Compressing and writing come in bursts; on a loaded machine a burst must not keep the
    driver threads off the CPU long enough for the board's buffer to overflow.  The
    recorder's privileged queue absorbs the delay instead.  (Linux: per-thread niceness.)
    """
    with contextlib.suppress(AttributeError, OSError):
        tid = threading.get_native_id()
        current = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(19, current + niceness))


class RecorderThread(threading.Thread):
    """Drains a (privileged) engine subscription into a ``Recorder`` and flushes on time.

    A write failure stops the thread and is handed to ``on_error`` at once (the
    procedure then ramps the drive to zero); the file keeps what was flushed.
    """

    def __init__(
        self,
        recorder: Recorder,
        source: EventSource,
        *,
        on_error: Callable[[Exception], None] | None = None,
    ) -> None:
        super().__init__(name=f"recorder:{recorder.path.name}", daemon=True)
        self.recorder = recorder
        self.source = source
        self.on_error = on_error
        self.error: Exception | None = None

    def run(self) -> None:
        _lower_this_threads_priority(RECORDER_NICENESS)
        try:
            while True:
                batch = self.source.get_many(timeout_s=self.recorder.flush_interval_s / 4)
                for host_time_s, event in batch:
                    self.recorder.add(event, host_time_s)
                if self.recorder.flush_due:
                    self.recorder.flush()
                if not batch and self.source.closed:
                    break
            self.recorder.flush()
        except Exception as error:  # surfaced through on_error and .error
            self.error = error
            if self.on_error is not None:
                self.on_error(error)
            if isinstance(error, DiskFullError):
                self._keep_annotations()

    def finish(self, progress: ProgressText | None = None) -> None:
        """Wait until the writer has written everything queued (call after the engine stopped).

        There is no time limit: the file must not be closed while this thread still writes
        to it, and a writer behind by seconds of samples still ends once its queue is empty.
        """
        while self.is_alive():
            self.join(1.0)
            if self.is_alive() and progress is not None:
                progress("finishing the file: writing what is still queued ...")

    def _keep_annotations(self) -> None:
        """After the disk filled: drain until the engine stops, keeping only drive settings and
        step marks (the recorder writes them into its reserve at close)."""
        while True:
            batch = self.source.get_many(timeout_s=0.1)
            for host_time_s, event in batch:
                self.recorder.add(event, host_time_s)  # blocks are refused quietly now
            if not batch and self.source.closed:
                return


class RecordingSubscriber(Protocol):
    """The part of the acquisition engine a recording needs (see ``rig.engine``)."""

    def subscribe(self, name: str, *, privileged: bool = ...) -> Any: ...

    def fail(self, error: BaseException) -> None: ...


def attach_recorder(engine: RecordingSubscriber, recorder: Recorder) -> RecorderThread:
    """Subscribe ``recorder`` to ``engine`` as the privileged subscriber and start writing.

    Call before ``engine.start()`` so that the first block is recorded.  A write error
    fails the engine (which stops acquisition and tells its failure callbacks).
    """
    subscription = engine.subscribe("recorder", privileged=True)
    thread = RecorderThread(recorder, subscription, on_error=engine.fail)
    thread.start()
    return thread
