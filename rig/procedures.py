"""Experiment procedures: free decay, impact decay, forced sweep, and a plain timed recording.

Each runs inside a ``ProcedureSession``: the engine reads the devices, the recorder
writes the file, and whatever happens (Ctrl-C, a device error, a full disk) the
shaker is ramped to zero and the file is closed valid, with the reason it stopped.
Decays wait for the release with a pre-trigger buffer (the file starts shortly
before the pendulum moved); sweeps mark every step with its setting in the file.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from analysis.experiments import FORCED, experiment_kind
from analysis.provenance import invocation_operator, provenance
from drivers.interfaces import DeviceError, SampleBlock
from rig.devices import ANGLE, TABLE, TACH, RigDevices
from rig.drive_monitor import DriveMonitor
from rig.engine import AcquisitionEngine, Delivery, Subscription
from rig.events import StepMark
from rig.recorder import Recorder, RecorderThread, RecordingMetadata

Progress = Callable[[str], None]
FIRST_DATA_TIMEOUT_S = 15.0  # generous: a loaded lab PC can be slow to start streaming
TRIGGER_SLACK_S = 2.0  # how late the release may be noticed without shortening the pre-trigger


class ProcedureError(RuntimeError):
    """A procedure could not run to its end; the message says why and what was kept."""


@dataclass(frozen=True)
class ProcedureResult:
    """What a procedure left behind."""

    path: Path
    experiment: str
    stop_reason: str
    samples_written: int
    samples_lost: int
    duration_s: float
    steps: int = 0
    lost_per_stream: dict[str, int] = field(default_factory=dict)


class PretriggerGate:
    """Holds the recorder's deliveries until ``open(index)``, keeping ``pretrigger`` samples.

    Sample blocks that end more than ``pretrigger_samples`` before the trigger index
    are dropped (they precede the recording); everything else passes unchanged.  While
    closed it holds ``slack_samples`` more than the pre-trigger: the trigger is found
    some time after the release, and the pre-trigger counts from the release.
    """

    def __init__(
        self, source: Subscription, pretrigger_samples: int, slack_samples: int = 0
    ) -> None:
        self.source = source
        self.pretrigger_samples = pretrigger_samples
        self.slack_samples = slack_samples
        self._held: deque[Delivery] = deque()
        self._newest_index = 0
        self._open = False
        self._lock = threading.Lock()

    @property
    def closed(self) -> bool:
        return self.source.closed and (self._open or not self._held)

    def open(self, trigger_index: int) -> None:
        """Let everything through from ``trigger_index - pretrigger_samples`` on."""
        with self._lock:
            self._trim(trigger_index - self.pretrigger_samples)
            self._open = True

    def _trim(self, first_kept: int) -> None:
        kept = deque()
        for host_time_s, event in self._held:
            ends_before = getattr(event, "end_index", None)
            if ends_before is not None and ends_before <= first_kept:
                continue
            kept.append((host_time_s, event))
        self._held = kept

    def get_many(self, timeout_s: float = 0.1) -> list[Delivery]:
        batch = self.source.get_many(timeout_s)
        with self._lock:
            if self._open:
                out = list(self._held) + batch
                self._held.clear()
                return out
            for delivery in batch:
                self._held.append(delivery)
                end = getattr(delivery[1], "end_index", None)
                if end is not None:
                    self._newest_index = max(self._newest_index, end)
            if len(self._held) > 64:
                self._trim(self._newest_index - self.pretrigger_samples - self.slack_samples)
            return []


class AngleWatch:
    """The procedure's own (dropping) view of the angle: the last few seconds, for triggers."""

    def __init__(self, subscription: Subscription, sample_rate_hz: float, keep_s: float = 4.0):
        self.subscription = subscription
        self.keep = max(16, int(keep_s * sample_rate_hz))
        self.values = np.zeros(0)
        self.end_index = 0

    def update(self) -> None:
        """Take what arrived since the last call."""
        blocks = [
            e
            for _, e in self.subscription.get_many(timeout_s=0.0)
            if isinstance(e, SampleBlock) and e.channel == ANGLE
        ]
        if blocks:
            self.values = np.concatenate([self.values, *[b.values for b in blocks]])[-self.keep :]
            self.end_index = blocks[-1].end_index

    def last(self, n: int) -> np.ndarray:
        """The newest ``n`` angle samples (fewer at the start)."""
        return self.values[-n:] if n > 0 else self.values[:0]


class ProcedureSession:
    """Engine, recorder and devices of one procedure: drive left at zero, file left valid."""

    def __init__(
        self,
        devices: RigDevices,
        path: str | Path,
        metadata: RecordingMetadata,
        *,
        overwrite: bool = False,
        compression: str | None = "auto",
        pretrigger_s: float | None = None,
        flush_interval_s: float = 0.5,
        progress: Progress | None = None,
    ) -> None:
        self.devices = devices
        self.progress = progress or (lambda text: None)
        self.fs = devices.sample_rate_hz
        self.recorder = Recorder(
            path,
            devices.channel_specs(),
            metadata,
            overwrite=overwrite,
            flush_interval_s=flush_interval_s,
            compression=compression,
        )
        self.engine = AcquisitionEngine(devices.streams)
        self.monitor = DriveMonitor(
            devices.shaker,
            self.engine,
            devices.config.drive_tolerance,
            where=devices.shaker.backend.description,
        )
        self._failed = threading.Event()
        self.engine.on_failure(lambda error: self._failed.set())
        subscription = self.engine.subscribe("recorder", privileged=True)
        self.gate = None
        source = subscription
        if pretrigger_s is not None:
            self.gate = PretriggerGate(
                subscription, round(pretrigger_s * self.fs), round(TRIGGER_SLACK_S * self.fs)
            )
            source = self.gate
        self.writer = RecorderThread(self.recorder, source, on_error=self.engine.fail)
        self.watch = AngleWatch(self.engine.subscribe("procedure", max_items=4000), self.fs)
        self.started = 0.0
        self.stop_reason = "completed"

    def __enter__(self) -> ProcedureSession:
        self.writer.start()
        self.started = time.monotonic()
        try:
            self.monitor.check_idle()  # before anything moves: nobody else drives the table
            self.engine.start()  # a stream that cannot start still leaves a closed, valid file
            self.monitor.start()
            if not self.wait(FIRST_DATA_TIMEOUT_S, until=lambda: self.engine.latest_index):
                raise ProcedureError(
                    f"no data from the DAQ board within {FIRST_DATA_TIMEOUT_S:g} s "
                    f"({self.devices.board.status().message or 'no message'})"
                )
        except BaseException as error:
            self.__exit__(type(error), error, error.__traceback__)
            raise
        return self

    def check(self) -> None:
        """Raise the failure that stopped acquisition or recording, if any."""
        self.engine.raise_if_failed()

    def wait(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Wait ``seconds`` (or until ``until()`` is true: returns True), watching for failures."""
        deadline = time.monotonic() + seconds
        while True:
            self.check()
            self.watch.update()
            if until is not None and until():
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self._failed.wait(min(0.05, remaining))

    def set_drive(self, frequency_hz: float, amplitude_m: float) -> None:
        """Command the drive (validated by the shaker's limits) and log it in the file."""
        shaker = self.devices.shaker
        with self.monitor.commanding(frequency_hz, amplitude_m, True):
            shaker.frequency_hz = frequency_hz
            shaker.amplitude_m = amplitude_m
            if not shaker.enabled:
                shaker.enabled = True
        self.engine.note_drive(frequency_hz, amplitude_m, True)

    def __exit__(self, kind, error, traceback) -> None:
        if kind is not None:
            self.stop_reason = (
                "interrupted (Ctrl-C)" if issubclass(kind, KeyboardInterrupt) else f"error: {error}"
            )
        self.monitor.stop()
        with contextlib.suppress(DeviceError):
            self.devices.shaker.stop()
        self.engine.note_drive(0.0, 0.0, False)
        if self.gate is not None:
            self.gate.open(self.engine.latest_index or 0)  # keep what was seen on a failure
        self.engine.stop()
        self.writer.finish(self.progress)  # never close the file under a writing thread
        if self.recorder.error is not None and kind is None:
            self.stop_reason = f"error: {self.recorder.error}"
        self.recorder.close(self.stop_reason)

    def result(self, experiment: str, steps: int = 0) -> ProcedureResult:
        """Summary after the session closed."""
        return ProcedureResult(
            path=self.recorder.path,
            experiment=experiment,
            stop_reason=self.stop_reason,
            samples_written=self.recorder.samples_written,
            samples_lost=self.engine.stats().samples_lost,
            lost_per_stream=self.engine.stats().lost_per_stream,
            duration_s=time.monotonic() - self.started,
            steps=steps,
        )


def base_metadata(
    devices: RigDevices, experiment: str, notes: str, drive: dict | None, plan: dict
) -> RecordingMetadata:
    """What every recording of a procedure carries."""
    config = devices.config
    return RecordingMetadata(
        provenance=provenance(operator=invocation_operator() or config.operator),
        experiment=experiment,
        notes=notes,
        rig=config.constants.as_exchange(),
        calibrations=config.calibrations(),
        devices=devices.identities(),
        config_toml=config.text,
        drive=drive,
        roles={"angle": ANGLE, "table": TABLE, "tach": TACH},
        extra={"plan": plan, "config_source": config.source},
    )


# -- timed recording --------------------------------------------------------------------------


@dataclass(frozen=True)
class TimedPlan:
    """Record for ``duration_s``; with a drive, run it (and let it settle) first."""

    experiment: str
    duration_s: float
    frequency_hz: float | None = None
    amplitude_m: float | None = None
    settle_s: float = 2.0


def record_timed(
    devices: RigDevices,
    path: str | Path,
    plan: TimedPlan,
    *,
    notes: str = "",
    overwrite: bool = False,
    progress: Progress | None = None,
    compression: str | None = "auto",
) -> ProcedureResult:
    """A plain recording: optional steady drive, then ``duration_s`` of data."""
    driven = plan.frequency_hz is not None and plan.amplitude_m is not None
    drive = {"frequency_hz": plan.frequency_hz, "amplitude_m": plan.amplitude_m} if driven else None
    meta = base_metadata(devices, plan.experiment, notes, drive, asdict(plan))
    progress = progress or (lambda text: None)
    session = ProcedureSession(
        devices, path, meta, overwrite=overwrite, progress=progress, compression=compression
    )
    with session:
        if driven:
            session.set_drive(plan.frequency_hz, plan.amplitude_m)
            progress(f"drive {plan.frequency_hz:g} Hz, {plan.amplitude_m * 1e3:g} mm: settling")
            session.wait(plan.settle_s)
        _wait_with_progress(session, plan.duration_s, progress, "recording")
    return session.result(plan.experiment)


def _wait_with_progress(session: ProcedureSession, seconds: float, progress: Progress, what: str):
    start = time.monotonic()
    while True:
        elapsed = time.monotonic() - start
        if elapsed >= seconds:
            return
        session.wait(min(1.0, seconds - elapsed))
        stats = session.engine.stats()
        progress(
            f"{what}: {min(elapsed + 1, seconds):.0f}/{seconds:.0f} s, "
            f"{stats.channels[ANGLE].samples_received} samples, {stats.samples_lost} lost"
        )


# -- decays -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class DecayPlan:
    """A free or impact decay: hold, release, record until the swing dies down."""

    experiment: str = "free_decay"  # or "impact_decay"
    release_angle_rad: float = -0.3
    pretrigger_s: float = 0.5
    trigger_rad: float = 0.005  # motion away from the held angle that counts as the release
    stop_below_rad: float = 0.005  # half peak-to-peak over the last window
    window_s: float = 1.0
    max_duration_s: float = 60.0
    release_timeout_s: float = 120.0


def record_decay(
    devices: RigDevices,
    path: str | Path,
    plan: DecayPlan,
    *,
    notes: str = "",
    overwrite: bool = False,
    progress: Progress | None = None,
    compression: str | None = "auto",
) -> ProcedureResult:
    """Free decay (barrier removed) or impact decay (barrier in): wait for the release with a
    pre-trigger buffer, then record until the amplitude falls below ``stop_below_rad``."""
    kind = experiment_kind(plan.experiment)
    if kind.driven:
        raise ValueError(f"experiment {plan.experiment!r}; expected free_decay or impact_decay")
    progress = progress or (lambda text: None)
    devices.set_barrier(kind.barrier)
    meta = base_metadata(devices, plan.experiment, notes, None, asdict(plan))
    session = ProcedureSession(
        devices,
        path,
        meta,
        overwrite=overwrite,
        compression=compression,
        pretrigger_s=plan.pretrigger_s,
        progress=progress,
    )
    fs = session.fs
    window = max(8, int(plan.window_s * fs))
    with session:
        devices.hold(plan.release_angle_rad)
        # let the held angle show in the data before letting go
        session.wait(plan.pretrigger_s + 0.3)
        held = (
            float(np.median(session.watch.last(int(0.2 * fs))))
            if session.watch.values.size
            else plan.release_angle_rad
        )
        devices.release(plan.release_angle_rad)
        progress("waiting for the release ...")

        def moved() -> bool:
            recent = session.watch.last(max(1, int(0.01 * fs)))
            return recent.size > 0 and bool(np.any(np.abs(recent - held) > plan.trigger_rad))

        if not session.wait(plan.release_timeout_s, until=moved):
            raise ProcedureError(
                f"the pendulum did not move within {plan.release_timeout_s:g} s "
                f"(more than {plan.trigger_rad} rad from {held:.4f} rad)"
            )
        trigger_index = _release_index(session.watch, held, plan.trigger_rad)
        session.gate.open(trigger_index)
        progress(
            f"released at sample {trigger_index}; recording until the swing is below "
            f"{plan.stop_below_rad} rad"
        )
        released_at = time.monotonic()

        def died_down() -> bool:
            recent = session.watch.last(window)
            if recent.size < window or time.monotonic() - released_at < plan.window_s:
                return False
            return float(np.ptp(recent)) / 2.0 < plan.stop_below_rad

        if not session.wait(plan.max_duration_s, until=died_down):
            session.stop_reason = f"completed (max duration {plan.max_duration_s:g} s reached)"
        else:
            session.stop_reason = "completed (amplitude below threshold)"
    return session.result(plan.experiment)


def _release_index(watch: AngleWatch, held: float, trigger_rad: float) -> int:
    """Sample index where the current excursion from the held angle began: the pre-trigger
    counts from the release itself, not from when a poll happened to notice it."""
    still = np.flatnonzero(np.abs(watch.values - held) <= trigger_rad)
    first_away = int(still[-1]) + 1 if still.size else 0
    return watch.end_index - watch.values.size + first_away


# -- forced sweep -----------------------------------------------------------------------------


@dataclass(frozen=True)
class SweepPlan:
    """Step the frequency (amplitude fixed) or the amplitude (frequency fixed) up, then down."""

    parameter: str  # "frequency" or "amplitude"
    values: tuple[float, ...]  # the upward steps; the way down repeats them in reverse
    fixed: float  # the other setting: amplitude_m for a frequency sweep, frequency_hz otherwise
    settle_s: float = 3.0
    dwell_s: float = 5.0
    down: bool = True

    def __post_init__(self) -> None:
        if self.parameter not in ("frequency", "amplitude"):
            raise ValueError(f"sweep parameter {self.parameter!r}; expected frequency|amplitude")
        if not self.values:
            raise ValueError("a sweep needs at least one step")
        if self.settle_s < 0 or self.dwell_s <= 0:
            raise ValueError("settle_s must be >= 0 and dwell_s > 0")

    def steps(self) -> list[tuple[int, float, float]]:
        """(direction, frequency_hz, amplitude_m) of every step in order."""
        up = [(1, v) for v in self.values]
        down = [(-1, v) for v in reversed(self.values[:-1])] if self.down else []
        out = []
        for direction, value in up + down:
            if self.parameter == "frequency":
                out.append((direction, value, self.fixed))
            else:
                out.append((direction, self.fixed, value))
        return out


def run_sweep(
    devices: RigDevices,
    path: str | Path,
    plan: SweepPlan,
    *,
    notes: str = "",
    overwrite: bool = False,
    progress: Progress | None = None,
    compression: str | None = "auto",
) -> ProcedureResult:
    """A forced-response sweep; each step is marked in the file (``/sweep_steps``)."""
    progress = progress or (lambda text: None)
    # every step is checked against the shaker's limits before anything moves
    limits = devices.shaker.limits
    for _, frequency_hz, amplitude_m in plan.steps():
        limits.check(
            "frequency_hz", frequency_hz, limits.min_frequency_hz, limits.max_frequency_hz, "Hz"
        )
        limits.check("amplitude_m", amplitude_m, 0.0, limits.max_amplitude_m, "m")
    first = plan.steps()[0]
    drive = {"frequency_hz": first[1], "amplitude_m": first[2]}
    meta = base_metadata(devices, FORCED.name, notes, drive, asdict(plan))
    session = ProcedureSession(
        devices, path, meta, overwrite=overwrite, progress=progress, compression=compression
    )
    steps = plan.steps()
    done = 0
    with session:
        for number, (direction, frequency_hz, amplitude_m) in enumerate(steps):
            session.set_drive(frequency_hz, amplitude_m)
            settle_start = session.engine.latest_index or 0
            arrow = "up" if direction > 0 else "down"
            progress(
                f"step {number + 1}/{len(steps)} {arrow}: {frequency_hz:g} Hz, "
                f"{amplitude_m * 1e3:g} mm, settling {plan.settle_s:g} s"
            )
            mark = StepMark(
                number,
                direction,
                frequency_hz,
                amplitude_m,
                settle_start,
                settle_start,
                settle_start,
                complete=False,
            )
            try:
                session.wait(plan.settle_s)
                dwell_start = session.engine.latest_index or settle_start
                mark = StepMark(
                    number,
                    direction,
                    frequency_hz,
                    amplitude_m,
                    settle_start,
                    dwell_start,
                    dwell_start,
                    complete=False,
                )
                progress(f"step {number + 1}/{len(steps)} {arrow}: dwell {plan.dwell_s:g} s")
                session.wait(plan.dwell_s)
            except BaseException:
                end = session.engine.latest_index or mark.dwell_start_index
                session.engine.mark_step(StepMark(**{**asdict(mark), "dwell_end_index": end}))
                raise
            end = session.engine.latest_index or dwell_start
            session.engine.mark_step(
                StepMark(
                    number,
                    direction,
                    frequency_hz,
                    amplitude_m,
                    settle_start,
                    dwell_start,
                    end,
                    complete=True,
                )
            )
            done += 1
    return session.result(FORCED.name, steps=done)
