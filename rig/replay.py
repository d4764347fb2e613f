"""Replay drivers: a recording played back through the ``InputStream`` interface.

The engine, the GUI and live analysis run unchanged on a recording: each channel of
the file becomes a stream delivering the blocks as the driver once delivered them
(same sample indices, device timestamps and gaps), paced in real time, ``speed``
times faster, or as fast as the reader takes them (``speed=math.inf``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

from analysis import quantities as q
from drivers.interfaces import PulseBlock, SampleBlock, StreamStatus
from recording.errors import RecordingFormatError
from recording.reader import Recording, open_recording
from rig.events import DriveSetting, StepMark


def iter_sample_blocks(
    recording: Recording, name: str, max_samples: int = 4096, slab_samples: int = 1 << 18
) -> Iterator[SampleBlock]:
    """A sampled channel's stored blocks as the driver delivered them, large blocks split.

    The file is read in slabs of ``slab_samples`` so that small blocks cost no HDF5 call each.
    """
    fs = recording.sample_rate_hz(name)
    slab_start = 0
    raw, values, flags = recording.read_samples(name, 0, 0)
    for row in recording.complete_blocks(name):
        start, n = int(row["stored_start"]), int(row["n_samples"])
        if start + n > slab_start + raw.size:
            slab_start = start
            raw, values, flags = recording.read_samples(name, start, start + max(n, slab_samples))
        base = start - slab_start
        for offset in range(0, n, max_samples):
            count = min(max_samples, n - offset)
            part = slice(base + offset, base + offset + count)
            yield SampleBlock(
                channel=name,
                first_index=int(row["first_index"]) + offset,
                timestamp_s=float(row["timestamp_s"]) + offset / fs,
                sample_rate_hz=fs,
                raw=raw[part],
                values=values[part].astype(float),
                lost_before=int(row["lost_before"]) if offset == 0 else 0,
                flags=flags[part],
            )


def iter_pulse_blocks(recording: Recording, name: str) -> Iterator[PulseBlock]:
    """A pulse channel's blocks as the driver delivered them."""
    data = recording.pulses(name)
    position = 0
    for row in data.covered:
        n = int(row["n_edges"])
        yield PulseBlock(
            channel=name,
            first_index=int(row["first_index"]),
            end_index=int(row["end_index"]),
            edge_indices=data.edge_indices[position : position + n],
            edge_times_s=data.edge_times_s[position : position + n],
            lost_before=int(row["lost_before"]),
        )
        position += n


class ReplayClock:
    """Shared pacing of the streams of one replay: index ``i`` is due at ``(i - i0) / fs / speed``.

    All channels of a board share the running index, so pacing on it keeps them together.
    """

    def __init__(self, speed: float, sample_rate_hz: float, first_index: int) -> None:
        if not speed > 0:
            raise ValueError(f"replay speed is {speed}; expected a positive number (inf: no wait)")
        self.speed = speed
        self.sample_rate_hz = sample_rate_hz
        self.first_index = first_index
        self._start: float | None = None
        self._lock = threading.Lock()

    def start(self) -> None:
        """Begin the replay's time at the first call (later calls keep it)."""
        with self._lock:
            if self._start is None:
                self._start = time.monotonic()

    def wait_s(self, end_index: int) -> float:
        """Seconds until the sample before ``end_index`` is due (<= 0: due now)."""
        if math.isinf(self.speed) or self._start is None:
            return 0.0
        due = self._start + (end_index - self.first_index) / self.sample_rate_hz / self.speed
        return due - time.monotonic()


class ReplayStream:
    """One recorded channel as an ``InputStream`` (sampled or pulse channel)."""

    def __init__(
        self,
        recording: Recording,
        channel: str,
        clock: ReplayClock,
        *,
        max_block_samples: int = 4096,
    ) -> None:
        self.recording = recording
        self.channel = channel
        self.clock = clock
        self.max_block_samples = max_block_samples
        self.is_pulse = channel in recording.pulse_names
        if not self.is_pulse and channel not in recording.channel_names:
            raise ValueError(
                f"{recording.path}: no channel {channel!r}; it has "
                f"{recording.channel_names + recording.pulse_names}"
            )
        self.unit = recording.unit(channel)
        self._rate = recording.sample_rate_hz(channel)
        self._blocks: Iterator[SampleBlock | PulseBlock] | None = None
        self._pending: SampleBlock | PulseBlock | None = None
        self._received = 0
        self._lost = 0
        self._running = False
        self.finished = False

    @property
    def sample_rate_hz(self) -> float:
        """The recorded channel's nominal rate."""
        return self._rate

    def start(self) -> None:
        """Start (or restart) playing from the beginning of the recording."""
        if self.is_pulse:
            self._blocks = iter_pulse_blocks(self.recording, self.channel)
        else:
            self._blocks = iter_sample_blocks(self.recording, self.channel, self.max_block_samples)
        self._pending = None
        self._running = True
        self.finished = False
        self.clock.start()

    def stop(self) -> None:
        """Stop playing."""
        self._running = False

    def read(self, timeout_s: float = 0.1) -> SampleBlock | PulseBlock | None:
        """The next recorded block once it is due, or None (nothing due, stopped or finished)."""
        if not self._running or self._blocks is None:
            time.sleep(timeout_s)
            return None
        if self._pending is None:
            self._pending = next(self._blocks, None)
            if self._pending is None:
                self.finished = True
                time.sleep(timeout_s)
                return None
        wait = self.clock.wait_s(self._pending.end_index)
        if wait > timeout_s:
            time.sleep(timeout_s)
            return None
        if wait > 0:
            time.sleep(wait)
        block, self._pending = self._pending, None
        self._received += block.end_index - block.first_index
        self._lost += block.lost_before
        return block

    def status(self) -> StreamStatus:
        """Samples played and gaps passed on so far."""
        message = "end of recording" if self.finished else ""
        return StreamStatus(self._running, self._received, self._lost, 0, message)


class AnnotationSink(Protocol):
    """Where replayed drive settings and step marks go (the acquisition engine)."""

    def publish(self, event: DriveSetting | StepMark) -> None: ...


def _annotation_index(event: DriveSetting | StepMark) -> int:
    """The sample index at which a drive setting or step mark was made."""
    return event.sample_index if isinstance(event, DriveSetting) else event.dwell_end_index


def step_marks(recording: Recording) -> list[StepMark]:
    """A recording's sweep step marks, as the sweep published them."""
    return [
        StepMark(
            int(r["step"]),
            int(r["direction"]),
            float(r[q.frequency_hz]),
            float(r[q.amplitude_m]),
            int(r["settle_start_index"]),
            int(r["dwell_start_index"]),
            int(r["dwell_end_index"]),
            bool(r["complete"]),
        )
        for r in recording.sweep_steps()
    ]


class Replay:
    """A recording opened for replay: its streams share one clock; close it when done."""

    def __init__(
        self,
        path: str | Path,
        *,
        speed: float = 1.0,
        channels: list[str] | None = None,
        max_block_samples: int = 4096,
    ) -> None:
        self.recording = open_recording(path)
        names = channels or self.recording.channel_names + self.recording.pulse_names
        try:
            self.recording.verify()  # damage refuses the file before a block is played
            for name in names:
                self.recording.sample_rate_hz(name)  # an unknown name fails here, clearly
        except RecordingFormatError:
            self.recording.close()
            raise
        first = [
            int(b["first_index"][0])
            for b in (self.recording.complete_blocks(c) for c in self.recording.channel_names)
            if b.size
        ]
        rates = [self.recording.sample_rate_hz(c) for c in names] or [1.0]
        self.clock = ReplayClock(speed, max(rates), min(first) if first else 0)
        self._annotations: threading.Thread | None = None
        self._closing = threading.Event()
        try:
            self.streams = [
                ReplayStream(self.recording, name, self.clock, max_block_samples=max_block_samples)
                for name in names
            ]
            # read now, before any stream's thread reads the file: the GUI's replay crashed
            # in HDF5 once (CI, a fresh clone) reading these on its own thread while the
            # engine's threads read blocks
            self._events = self.annotations()
        except (ValueError, RecordingFormatError):
            self.recording.close()
            raise

    @property
    def finished(self) -> bool:
        """True when every stream has played its last block (and the annotations theirs)."""
        annotations_done = self._annotations is None or not self._annotations.is_alive()
        return annotations_done and all(stream.finished for stream in self.streams)

    def annotations(self) -> list[DriveSetting | StepMark]:
        """The recording's drive settings and sweep step marks, in sample-index order."""
        drive = [
            DriveSetting(
                float(r["host_time_s"]),
                int(r["sample_index"]),
                float(r[q.frequency_hz]),
                float(r[q.amplitude_m]),
                bool(r["enabled"]),
                int(r["source"]),
            )
            for r in self.recording.drive_log()
        ]
        return sorted(drive + step_marks(self.recording), key=_annotation_index)

    def publish_annotations(self, engine: AnnotationSink) -> None:
        """Publish the drive settings and step marks into ``engine`` when their sample is due.

        Runs in its own thread, from the events read when the replay was opened; call
        after ``engine.start()``.
        """
        events = self._events

        def play() -> None:
            for event in events:
                while (wait := self.clock.wait_s(_annotation_index(event))) > 0:
                    if self._closing.wait(min(wait, 0.1)):
                        return
                engine.publish(event)

        self._annotations = threading.Thread(target=play, name="replay-annotations", daemon=True)
        self._annotations.start()

    def close(self) -> None:
        """Stop publishing annotations and release the file."""
        self._closing.set()
        if self._annotations is not None:
            self._annotations.join(5.0)
        self.recording.close()

    def __enter__(self) -> Replay:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
