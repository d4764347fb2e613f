"""The bridge between the GUI and the rig: sessions that own an engine; a background task runner.

Acquisition runs in the engine's own threads and recording in the recorder's thread;
the GUI only drains its own bounded subscription on a timer.  Everything that may
block (opening devices, Modbus commands to the shaker, closing a recording, a sweep,
identification) runs on a :class:`TaskRunner` thread and reports back through Qt
signals, which Qt delivers on the GUI thread.  A sweep is ``impact-rig sweep``'s own
procedure (``rig.procedures.run_sweep``) run on the live engine: the GUI only shows it.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from analysis import quantities as q
from analysis.progress import ProgressText
from drivers.interfaces import ActuatorStatus, DeviceError, PulseBlock, SampleBlock, StreamStatus
from drivers.shaker import ShakerAmplifier
from recording.reader import open_recording
from rig.config import RigConfig
from rig.devices import RigDevices, open_rig
from rig.engine import AcquisitionEngine, EngineStats, Subscription
from rig.procedures import (
    Cancel,
    ProcedureResult,
    SweepPlan,
    base_metadata,
    check_drives,
    run_sweep,
)
from rig.recorder import Recorder, RecorderThread, attach_recorder
from rig.replay import Replay, step_marks

VIEW_QUEUE_ITEMS = 4000  # the GUI's own bounded queue; when full it loses only its own view
OPERATOR_STOP = "stopped by the operator"  # why a file ends when the operator ended it
RAMP_DOWN_TIMEOUT_S = 30.0  # a hand-set drive ramping to zero before a sweep takes over
SWEEP_END_TIMEOUT_S = 10.0  # closing the rig waits this long for a cancelled sweep to end


@dataclass(frozen=True)
class _Outcome:
    """A finished background call and whom to tell."""

    on_done: Callable[[object], None] | None
    on_error: Callable[[BaseException], None] | None
    result: object
    error: BaseException | None


class TaskRunner(QObject):
    """Runs blocking calls one after another on a background thread; answers on the GUI thread."""

    _finished = Signal(object)  # an _Outcome (never a bare None: PySide6 mis-counts its refs)

    def __init__(self, name: str, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)
        self._finished.connect(self._deliver)
        self.pending = 0

    def submit(
        self,
        work: Callable[[], object],
        on_done: Callable[[object], None] | None = None,
        on_error: Callable[[BaseException], None] | None = None,
    ) -> Future:
        """Run ``work()`` in the background; ``on_done(result)`` or ``on_error(error)`` later."""
        self.pending += 1

        def finished(future: Future) -> None:
            error = future.exception()
            result = None if error is not None else future.result()
            with contextlib.suppress(RuntimeError):  # the runner was deleted at exit
                self._finished.emit(_Outcome(on_done, on_error, result, error))

        future = self._executor.submit(work)
        future.add_done_callback(finished)
        return future

    def _deliver(self, outcome: _Outcome) -> None:
        self.pending -= 1
        if outcome.error is not None:
            if outcome.on_error is not None:
                outcome.on_error(outcome.error)
        elif outcome.on_done is not None:
            outcome.on_done(outcome.result)

    def shutdown(self, wait: bool = True) -> None:
        """Finish what was submitted and stop the thread."""
        self._executor.shutdown(wait=wait)


class RecordingRun:
    """One recording of the live engine, written by the recorder's own thread."""

    def __init__(self, engine: AcquisitionEngine, recorder: Recorder) -> None:
        self.engine = engine
        self.recorder = recorder
        self.path = recorder.path
        self.started = time.monotonic()
        self.thread: RecorderThread = attach_recorder(engine, recorder)
        self.stopped = False

    @property
    def elapsed_s(self) -> float:
        """Seconds since recording started."""
        return time.monotonic() - self.started

    @property
    def file_size_bytes(self) -> int:
        """Size of the file on disk (grows at each flush)."""
        with contextlib.suppress(OSError):
            return os.stat(self.path).st_size
        return 0

    def stop(self, reason: str = OPERATOR_STOP) -> Path:
        """Stop feeding the recorder, let it write what it holds, close the file (blocking)."""
        if self.stopped:
            return self.path
        self.stopped = True
        self.engine.unsubscribe(self.thread.source)  # the thread drains the rest, then ends
        self.thread.join(30.0)
        if self.recorder.error is not None:
            reason = f"error: {self.recorder.error}"
        self.recorder.close(reason)
        return self.path


class Session:
    """What the views need from a data source: an engine, the GUI's queue, rates and health."""

    kind = "none"
    engine: AcquisitionEngine | None = None
    view: Subscription | None = None
    sample_rate_hz: float = 1.0
    title = ""

    def drain(self) -> list[object]:
        """Everything queued for the GUI since the last call (never waits)."""
        if self.view is None:
            return []
        return [event for _, event in self.view.get_many(timeout_s=0.0)]

    def stats(self) -> EngineStats | None:
        """The engine's live quantities, or None when nothing runs."""
        return self.engine.stats() if self.engine is not None else None

    def stream_statuses(self) -> list[tuple[str, StreamStatus]]:
        """Each input stream's own health report."""
        if self.engine is None:
            return []
        out = []
        for stream in self.engine.streams:
            try:
                out.append((stream.channel, stream.status()))
            except Exception as error:  # a broken driver must not break the status panel
                out.append(
                    (stream.channel, StreamStatus(False, 0, 0, 0, f"status failed: {error}"))
                )
        return out

    def close(self) -> None:
        """Stop everything the session runs."""


class LiveSession(Session):
    """The rig (virtual or real) with the engine running and the drive under control."""

    kind = "live"

    def __init__(self, devices: RigDevices) -> None:
        self.devices = devices
        self.config: RigConfig = devices.config
        self.engine = AcquisitionEngine(devices.streams)
        self.view = self.engine.subscribe("gui", max_items=VIEW_QUEUE_ITEMS)
        self.sample_rate_hz = devices.sample_rate_hz
        self.title = f"{self.config.name} ({'virtual' if self.config.is_virtual else 'real'})"
        self.recording: RecordingRun | None = None
        self._sweep_cancel: Cancel | None = None  # the running sweep's, None between sweeps
        self._sweep_ended = threading.Event()
        self._sweep_ended.set()
        self._lock = threading.Lock()
        self._closed = False

    @classmethod
    def open(cls, config: RigConfig, sample_rate_hz: float | None = None) -> LiveSession:
        """Open the devices (starting the virtual rig if the file says so) and start acquiring.

        Blocking: call it on a TaskRunner.
        """
        devices = open_rig(config, sample_rate_hz=sample_rate_hz)
        try:
            session = cls(devices)
            session.engine.start()
        except BaseException:
            devices.close()
            raise
        return session

    @property
    def limits(self):
        """The shaker's configured limits (drivers.limits.ShakerLimits)."""
        return self.devices.shaker.limits

    # -- drive (blocking: call on a TaskRunner) -------------------------------------------------

    def check_drive(
        self, frequency_hz: float, amplitude_m: float, ramp_rate_m_s: float | None = None
    ) -> None:
        """LimitError naming the setting when a value is outside the configured limits."""
        ramp = {} if ramp_rate_m_s is None else {"ramp_rate_m_s": ramp_rate_m_s}
        ShakerAmplifier.check_settings(
            self.limits, frequency_hz=frequency_hz, amplitude_m=amplitude_m, **ramp
        )

    def apply_drive(
        self,
        frequency_hz: float,
        amplitude_m: float,
        enabled: bool,
        ramp_rate_m_s: float | None = None,
    ) -> None:
        """Send the drive settings (all checked first, so a refused one sends nothing)."""
        self.check_drive(frequency_hz, amplitude_m, ramp_rate_m_s)
        shaker = self.devices.shaker
        with self._lock:
            if ramp_rate_m_s is not None:
                shaker.ramp_rate_m_s = ramp_rate_m_s
            shaker.frequency_hz = frequency_hz
            shaker.amplitude_m = amplitude_m
            if enabled:
                shaker.enabled = True
            else:
                shaker.stop()
        self.engine.note_drive(frequency_hz, amplitude_m, enabled)

    def stop_drive(self) -> None:
        """Ramp the drive to zero and disable it (the stop button): a running sweep is cancelled
        too, and the ramp starts at once, not when the sweep notices."""
        self.cancel_sweep()
        self._ramp_to_zero()

    def _ramp_to_zero(self, wait_s: float = 0.0) -> None:
        """Drive off; with ``wait_s``, wait (at most that long) until the output is at zero."""
        with self._lock:
            self.devices.shaker.stop(wait_s)
        self.engine.note_drive(0.0, 0.0, False)

    def shaker_status(self) -> ActuatorStatus:
        """Connection, measured output and faults of the amplifier (never raises)."""
        return self.devices.shaker.status()

    def clear_faults(self) -> None:
        """Clear the amplifier's latched faults whose cause is gone."""
        with self._lock:
            self.devices.shaker.clear_faults()

    # -- recording ------------------------------------------------------------------------------

    def start_recording(
        self,
        path: str | Path,
        notes: str = "",
        experiment: str = "forced",
        plan: dict | None = None,
    ) -> RecordingRun:
        """Start writing everything the engine delivers from now on to ``path``."""
        if self.recording is not None and not self.recording.stopped:
            raise RuntimeError(f"already recording to {self.recording.path}")
        drive = self.engine.stats().drive
        drive_meta = (
            {q.frequency_hz: drive.frequency_hz, q.amplitude_m: drive.amplitude_m}
            if drive is not None and drive.enabled
            else None
        )
        meta = base_metadata(
            self.devices, experiment, notes, drive_meta, plan or {"source": "impact-rig gui"}
        )
        recorder = Recorder(path, self.devices.channel_specs(), meta)
        self.recording = RecordingRun(self.engine, recorder)
        if drive is not None:
            self.engine.publish(drive)  # the file starts with the drive in force
        return self.recording

    def stop_recording(self) -> Path | None:
        """Close the current recording (blocking: call on a TaskRunner)."""
        run = self.recording
        if run is None:
            return None
        return run.stop()

    # -- sweeps (``impact-rig sweep``'s procedure on the live engine) -----------------------------

    def run_sweep(
        self,
        plan: SweepPlan,
        path: str | Path,
        notes: str = "",
        progress: ProgressText | None = None,
    ) -> ProcedureResult:
        """Run ``rig.procedures.run_sweep`` on the live engine (blocking: call on a TaskRunner).

        The same procedure, checks, events and file as ``impact-rig sweep``.  A plan the
        shaker's limits forbid is refused (LimitError) before anything moves.  The sweep
        takes over the drive: one left on by hand ramps to zero first, so the procedure
        starts from rest as on the command line.  ``cancel_sweep`` or STOP end it.
        """
        if self.recording is not None and not self.recording.stopped:
            raise RuntimeError(f"already recording to {self.recording.path}")
        # as the command line does before it opens the rig: a refused plan moves nothing,
        # not even the hand-set drive (run_sweep checks again, the same way)
        check_drives(self.limits, self.config.source, [(f, a) for _, f, a in plan.steps()])
        cancel = Cancel()
        self._sweep_cancel = cancel
        self._sweep_ended.clear()
        try:
            self._ramp_to_zero(RAMP_DOWN_TIMEOUT_S)
            return run_sweep(
                self.devices,
                path,
                plan,
                notes=notes,
                progress=progress,
                engine=self.engine,
                cancel=cancel,
            )
        finally:
            self._sweep_cancel = None
            self._sweep_ended.set()

    def cancel_sweep(self) -> None:
        """Stop the running sweep at its next wait (the drive ramps to zero, the file is closed
        saying the operator stopped it); nothing when no sweep runs."""
        cancel = self._sweep_cancel
        if cancel is not None:
            cancel.request(OPERATOR_STOP)

    def close(self) -> None:
        """Drive to zero, close the recording, stop acquiring, release the devices."""
        if self._closed:
            return
        self._closed = True
        self.cancel_sweep()
        self._sweep_ended.wait(SWEEP_END_TIMEOUT_S)  # the sweep closes its own file
        with contextlib.suppress(DeviceError):
            self.devices.shaker.stop()
        if self.recording is not None:
            with contextlib.suppress(Exception):
                self.recording.stop("application closed")
        self.engine.stop()
        self.devices.close()


@dataclass(frozen=True)
class RecordingSpan:
    """First and one-past-last sample index of a recording, and its rate."""

    first_index: int
    end_index: int
    sample_rate_hz: float

    @property
    def duration_s(self) -> float:
        """Length of the recording in seconds."""
        return (self.end_index - self.first_index) / self.sample_rate_hz


class _FromIndex:
    """A replay stream that skips the blocks before ``start_index`` (seeking)."""

    def __init__(self, stream, start_index: int) -> None:
        self._stream = stream
        self.start_index = start_index
        self.channel = stream.channel
        self.unit = stream.unit

    @property
    def sample_rate_hz(self) -> float:
        return self._stream.sample_rate_hz

    def start(self) -> None:
        self._stream.start()

    def stop(self) -> None:
        self._stream.stop()

    def status(self) -> StreamStatus:
        return self._stream.status()

    def read(self, timeout_s: float = 0.1) -> SampleBlock | PulseBlock | None:
        deadline = time.monotonic() + timeout_s
        while True:
            block = self._stream.read(max(0.0, min(timeout_s, deadline - time.monotonic())))
            if block is None or block.end_index > self.start_index:
                return block
            if time.monotonic() > deadline:
                return None


class ReplaySession(Session):
    """A recording played through the replay drivers and an engine: play, pause, seek, speed."""

    kind = "replay"

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        with open_recording(self.path) as recording:
            angle = recording.role("angle") or recording.channel_names[0]
            blocks = recording.complete_blocks(angle)
            if not blocks.size:
                raise ValueError(f"{self.path}: the recording holds no samples")
            self.span = RecordingSpan(
                int(blocks["first_index"][0]),
                int(blocks["first_index"][-1] + blocks["n_samples"][-1]),
                recording.sample_rate_hz(angle),
            )
            self.info = recording.info
            self.steps = step_marks(recording)
        self.sample_rate_hz = self.span.sample_rate_hz
        self.title = f"replay of {self.path.name}"
        self.speed = 1.0
        self.position_index = self.span.first_index
        self._replay: Replay | None = None

    @property
    def playing(self) -> bool:
        """True while the replay engine runs."""
        return self.engine is not None and self.engine.running

    @property
    def finished(self) -> bool:
        """True when the whole recording was played."""
        return self._replay is not None and self._replay.finished

    def play(self, start_index: int | None = None, speed: float | None = None) -> None:
        """Play from ``start_index`` (default: where it stopped) at ``speed`` (inf: at once)."""
        self.pause()
        if speed is not None:
            if not speed > 0:
                raise ValueError(f"replay speed {speed}: expected > 0 (inf: as fast as possible)")
            self.speed = speed
        if start_index is not None:
            self.position_index = int(
                min(max(start_index, self.span.first_index), self.span.end_index - 1)
            )
        replay = Replay(self.path, speed=self.speed)
        replay.clock.first_index = self.position_index  # what precedes the seek is due at once
        streams = [_FromIndex(stream, self.position_index) for stream in replay.streams]
        self.engine = AcquisitionEngine(streams)
        self.view = self.engine.subscribe("gui", max_items=VIEW_QUEUE_ITEMS)
        self._replay = replay
        self.engine.start()
        replay.publish_annotations(self.engine)

    def pause(self) -> None:
        """Stop playing; ``play()`` continues from the last sample shown."""
        if self.engine is not None:
            latest = self.engine.latest_index
            if latest is not None:
                self.position_index = latest
            self.engine.stop()
        if self._replay is not None:
            self._replay.close()
            self._replay = None

    def note_position(self, index: int | None) -> None:
        """The newest index the views have drawn (where pause resumes)."""
        if index is not None:
            self.position_index = index

    def close(self) -> None:
        self.pause()


def speed_from_text(text: str) -> float:
    """'1x', '4', 'max' -> replay speed (math.inf for as fast as possible)."""
    cleaned = text.strip().lower()
    if cleaned in ("max", "asap", "inf"):
        return math.inf
    return float(cleaned.removesuffix("x").strip())
