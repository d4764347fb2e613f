"""Crash-safe HDF5 recorder: engine events appended to a SWMR file, flushed at least every second.

The layout is documented in docs/recording_layout.md.  Events are buffered in memory
and written in one append per dataset at each flush, which keeps the cost per block
small at high sample rates; the file is readable (SWMR) while it is written and
holds everything up to the last flush if the process dies.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from rig.events import DriveSetting, Event, Gap, StepMark

FORMAT_NAME = "impact-rig recording"
FORMAT_VERSION = 2  # 2: per-sample status flags of every sampled channel
DEFAULT_FLUSH_INTERVAL_S = 0.5
MAX_FLUSH_INTERVAL_S = 1.0
STOP_REASON_BYTES = 256
FAST_CHANNEL_HZ = 50_000.0  # above this rate channels are compressed with lzf, not gzip
DISK_RESERVE_BYTES = 1 << 20  # kept free besides what the next flush may need
RECORDER_NICENESS = 5  # the writer thread runs this much "nicer" than acquisition

SAMPLE_BLOCK_DTYPE = np.dtype(
    [
        ("first_index", "<i8"),
        ("n_samples", "<i8"),
        ("stored_start", "<i8"),
        ("timestamp_s", "<f8"),
        ("host_time_s", "<f8"),
        ("lost_before", "<i8"),
    ]
)
PULSE_BLOCK_DTYPE = np.dtype(
    [
        ("first_index", "<i8"),
        ("end_index", "<i8"),
        ("host_time_s", "<f8"),
        ("lost_before", "<i8"),
        ("n_edges", "<i8"),
    ]
)
GAP_DTYPE = np.dtype([("start_index", "<i8"), ("length", "<i8")])
DRIVE_DTYPE = np.dtype(
    [
        ("host_time_s", "<f8"),
        ("sample_index", "<i8"),
        ("frequency_hz", "<f8"),
        ("amplitude_m", "<f8"),
        ("enabled", "u1"),
        ("source", "u1"),
    ]
)
STEP_DTYPE = np.dtype(
    [
        ("step", "<i4"),
        ("direction", "i1"),
        ("frequency_hz", "<f8"),
        ("amplitude_m", "<f8"),
        ("settle_start_index", "<i8"),
        ("dwell_start_index", "<i8"),
        ("dwell_end_index", "<i8"),
        ("complete", "u1"),
    ]
)
STATUS_DTYPE = np.dtype(
    [
        ("end_host_time_s", "<f8"),
        ("samples_written", "<i8"),
        ("samples_lost", "<i8"),
        ("flushes", "<i8"),
        ("closed", "u1"),
        ("stop_reason", f"S{STOP_REASON_BYTES}"),
    ]
)


class RecordingError(RuntimeError):
    """The recording cannot be created or written; the message names the file and the cause."""


class RecordingExistsError(RecordingError):
    """The output file exists and overwriting was not asked for."""


class DiskFullError(RecordingError):
    """The disk is (almost) full: recording stopped before a write could fail half-way."""


@dataclass(frozen=True)
class ChannelSpec:
    """One channel to record: ``kind`` is 'samples' (SampleBlock) or 'pulses' (PulseBlock)."""

    name: str
    kind: str = "samples"
    unit: str = ""
    sample_rate_hz: float = 0.0
    device: str = ""
    calibration: dict[str, Any] | None = None
    raw_dtype: str = "int32"

    def __post_init__(self) -> None:
        if self.kind not in ("samples", "pulses"):
            raise ValueError(
                f"channel {self.name!r}: kind is {self.kind!r}; expected 'samples' or 'pulses'"
            )
        if not self.name or "/" in self.name:
            raise ValueError(f"channel name {self.name!r} must be non-empty and contain no '/'")


@dataclass(frozen=True)
class RecordingMetadata:
    """What a recording must carry to be analysed years later (root attributes of the file)."""

    experiment: str
    notes: str = ""
    rig: dict[str, float | None] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    devices: dict[str, Any] = field(default_factory=dict)
    config_toml: str = ""
    drive: dict[str, float] | None = None
    roles: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    start_time_utc: str = ""


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


def _chunk_length(sample_rate_hz: float) -> int:
    """About one second of samples per chunk, between 4096 and 65536 elements."""
    target = max(4096, min(65536, int(sample_rate_hz)))
    return 1 << (target - 1).bit_length() if target < 65536 else 65536


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
        self._drive: list[tuple] = []
        self._steps: list[tuple] = []
        self._last_host_time_s = 0.0
        self._flushes = 0
        self._last_flush = time.monotonic()
        self._failed: RecordingError | None = None
        self._closed = False
        self._chunk_bytes = sum(
            _chunk_length(spec.sample_rate_hz) * (5 + np.dtype(spec.raw_dtype).itemsize)
            for spec in channels
        )
        if overwrite and self.path.exists():
            self.path.unlink()
        try:
            self._file = h5py.File(self.path, "w-", libver="latest")
        except OSError as error:
            raise RecordingError(f"{self.path}: cannot create the file ({error})") from None
        try:
            self._create_layout(channels, metadata, compression)
            self._file.swmr_mode = True
            self._write_status(closed=False, reason="recording")
            self._file.flush()
        except (OSError, ValueError) as error:
            self._abandon()
            with contextlib.suppress(OSError):  # the stub just created holds no data: a retry
                self.path.unlink()  # must not be refused as "already exists"
            raise RecordingError(f"{self.path}: cannot set up the file ({error})") from None

    # -- layout -------------------------------------------------------------------------------

    def _create_layout(
        self, channels: list[ChannelSpec], meta: RecordingMetadata, compression: str | None
    ) -> None:
        f = self._file
        f.attrs["format"] = FORMAT_NAME
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["software_version"] = software_version()
        f.attrs["start_time_utc"] = meta.start_time_utc or datetime.now(UTC).isoformat()
        f.attrs["experiment"] = meta.experiment
        f.attrs["notes"] = meta.notes
        f.attrs["rig_json"] = json.dumps(meta.rig)
        f.attrs["calibrations_json"] = json.dumps(meta.calibrations)
        f.attrs["devices_json"] = json.dumps(meta.devices)
        f.attrs["config_toml"] = meta.config_toml
        f.attrs["drive_json"] = json.dumps(meta.drive)
        f.attrs["roles_json"] = json.dumps(meta.roles)
        f.attrs["extra_json"] = json.dumps(meta.extra)
        samples = f.create_group("channels")
        pulses = f.create_group("pulses")
        for spec in channels:
            packed = _packing(compression, spec.sample_rate_hz)
            group = (samples if spec.kind == "samples" else pulses).create_group(spec.name)
            group.attrs["kind"] = spec.kind
            group.attrs["unit"] = spec.unit
            group.attrs["sample_rate_hz"] = float(spec.sample_rate_hz)
            group.attrs["device"] = spec.device
            group.attrs["calibration_json"] = json.dumps(spec.calibration)
            chunk = _chunk_length(spec.sample_rate_hz)
            if spec.kind == "samples":
                group.create_dataset(
                    "raw", (0,), maxshape=(None,), dtype=spec.raw_dtype, chunks=(chunk,), **packed
                )
                group.create_dataset(
                    "values", (0,), maxshape=(None,), dtype="<f4", chunks=(chunk,), **packed
                )
                group.create_dataset(
                    "flags", (0,), maxshape=(None,), dtype="u1", chunks=(chunk,), **packed
                )
                _table(group, "blocks", SAMPLE_BLOCK_DTYPE)
            else:
                for name, dtype in (("edge_indices", "<i8"), ("edge_times_s", "<f8")):
                    group.create_dataset(
                        name, (0,), maxshape=(None,), dtype=dtype, chunks=(1024,), **packed
                    )
                _table(group, "blocks", PULSE_BLOCK_DTYPE)
            _table(group, "gaps", GAP_DTYPE)
        _table(f, "drive", DRIVE_DTYPE)
        _table(f, "sweep_steps", STEP_DTYPE)
        f.create_dataset("status", (1,), dtype=STATUS_DTYPE)

    # -- writing ------------------------------------------------------------------------------

    @property
    def samples_written(self) -> int:
        """Samples of all sampled channels stored or waiting for the next flush."""
        return sum(b.stored for b in self._buffers.values() if b.spec.kind == "samples")

    @property
    def samples_lost(self) -> int:
        """Samples recorded as gaps, all channels."""
        return sum(b.lost for b in self._buffers.values())

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
            n = len(event)
            flags = np.zeros(n, "u1") if event.flags is None else np.asarray(event.flags, "u1")
            if flags.shape != (n,):
                raise ValueError(f"channel {event.channel!r}: {flags.size} flags for {n} samples")
            buffer.raw.append(np.asarray(event.raw))
            buffer.values.append(np.asarray(event.values, dtype="<f4"))
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
        elif isinstance(event, PulseBlock):
            buffer = self._channel(event.channel, "pulses")
            edges = np.asarray(event.edge_indices, dtype="<i8")
            buffer.edges.append(edges)
            buffer.edge_times.append(np.asarray(event.edge_times_s, dtype="<f8"))
            buffer.blocks.append(
                (event.first_index, event.end_index, host_time_s, event.lost_before, edges.size)
            )
            buffer.stored += edges.size
        elif isinstance(event, Gap):
            buffer = self._channel(event.channel, None)
            buffer.gaps.append((event.start_index, event.length))
            buffer.lost += event.length
        elif isinstance(event, DriveSetting | StepMark):
            self._add_annotation(event)
        else:
            raise TypeError(f"cannot record {type(event).__name__}")

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
        return total + 64 * (len(self._drive) + len(self._steps))

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
            _append(self._file["drive"], self._drive, DRIVE_DTYPE)
            _append(self._file["sweep_steps"], self._steps, STEP_DTYPE)
            self._drive.clear()
            self._steps.clear()
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
        group = self._file[f"{'channels' if buffer.spec.kind == 'samples' else 'pulses'}"][
            buffer.spec.name
        ]
        # Data before the tables that point into them: a reader after a crash keeps the
        # rows whose samples are present.
        if buffer.spec.kind == "samples":
            _append(group["raw"], buffer.raw, None)
            _append(group["values"], buffer.values, None)
            _append(group["flags"], buffer.flags, None)
            _append(group["blocks"], buffer.blocks, SAMPLE_BLOCK_DTYPE)
        else:
            _append(group["edge_indices"], buffer.edges, None)
            _append(group["edge_times_s"], buffer.edge_times, None)
            _append(group["blocks"], buffer.blocks, PULSE_BLOCK_DTYPE)
        _append(group["gaps"], buffer.gaps, GAP_DTYPE)
        buffer.clear()

    def _write_status(self, *, closed: bool, reason: str) -> None:
        row = np.zeros(1, dtype=STATUS_DTYPE)
        row["end_host_time_s"] = self._last_host_time_s
        row["samples_written"] = self.samples_written
        row["samples_lost"] = self.samples_lost
        row["flushes"] = self._flushes
        row["closed"] = int(closed)
        row["stop_reason"] = reason.encode("utf-8")[:STOP_REASON_BYTES]
        self._file["status"][0] = row[0]

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
            _append(self._file["drive"], self._drive, DRIVE_DTYPE)
            _append(self._file["sweep_steps"], self._steps, STEP_DTYPE)
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


def _packing(compression: str | None, sample_rate_hz: float) -> dict[str, Any]:
    """Filters of a channel's datasets.  'auto': gzip level 1 (readable by every HDF5 tool)
    up to FAST_CHANNEL_HZ, lzf above it (2-3 times less CPU for ~10 % more bytes)."""
    if compression == "auto":
        compression = "lzf" if sample_rate_hz > FAST_CHANNEL_HZ else "gzip"
    if compression not in ("gzip", "lzf", None):
        raise ValueError(f"compression {compression!r}; expected 'auto', 'gzip', 'lzf' or None")
    packed: dict[str, Any] = {"compression": compression, "shuffle": compression is not None}
    if compression == "gzip":
        packed["compression_opts"] = 1
    return packed


def _table(group: h5py.Group, name: str, dtype: np.dtype) -> None:
    group.create_dataset(name, (0,), maxshape=(None,), dtype=dtype, chunks=(256,))


def _append(dataset: h5py.Dataset, pending: list, dtype: np.dtype | None) -> None:
    """Append the pending arrays (or table rows) to a resizable 1-D dataset."""
    if not pending:
        return
    data = np.array(pending, dtype=dtype) if dtype is not None else np.concatenate(pending)
    if data.size == 0:
        return
    start = dataset.shape[0]
    dataset.resize((start + data.size,))
    dataset[start:] = data


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

    def finish(self, progress: Callable[[str], None] | None = None) -> None:
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
