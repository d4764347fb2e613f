"""Experiment procedures: free decay, impact decay, forced sweep, and a plain timed recording.

Each runs inside a ``ProcedureSession``: the engine reads the devices, the recorder
writes the file, and whatever happens (Ctrl-C, a ``Cancel`` from another thread, a
device error, a full disk) the shaker is ramped to zero and the file is closed valid,
with the reason it stopped.  The engine is the procedure's own (the command line) or
one already running on the devices (the GUI's live view), so both write the same file.
Decays wait for the release with a pre-trigger buffer (the file starts shortly
before the pendulum moved); sweeps mark every step with its setting in the file.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from analysis import quantities as q
from analysis.experiment_plan import ExperimentPlan
from analysis.experiments import FORCED, experiment_kind
from analysis.progress import ProgressText
from analysis.provenance import invocation_operator, provenance
from drivers.interfaces import DeviceError, LimitError, SampleBlock
from drivers.limits import ShakerLimits
from drivers.shaker import ShakerAmplifier
from rig.devices import ANGLE, TABLE, TACH, RigDevices
from rig.drive_monitor import DriveMonitor
from rig.engine import (
    AcquisitionEngine,
    AcquisitionError,
    Delivery,
    SubscriberOverrunError,
    Subscription,
)
from rig.events import COMMANDED, DriveSetting, StepBegun, StepMark
from rig.recorder import Recorder, RecorderThread, RecordingError, RecordingMetadata

FIRST_DATA_TIMEOUT_S = 15.0  # generous: a loaded lab PC can be slow to start streaming
TRIGGER_SLACK_S = 2.0  # how late the release may be noticed without shortening the pre-trigger
# A wait counted on the samples that sees no new sample this long (wall clock) ends the
# procedure: the stream stopped (a slow one, as a loaded PC's virtual rig, is waited for)
SAMPLES_STALL_S = 15.0


class ProcedureError(RuntimeError):
    """A procedure could not run to its end; the message says why and what was kept."""


class ProcedureCancelledError(ProcedureError):
    """Raised at a procedure's next wait once its ``Cancel`` was requested; the session ends
    the procedure there, closes the file with the request's reason and returns normally."""


# What a procedure on the rig fails with once it has started: the devices, the limits, the
# recording, the acquisition or the procedure itself.  The CLI and the demo turn these into
# their own errors (the drive is then at zero and the file keeps what was recorded).
RIG_FAILURES: tuple[type[Exception], ...] = (
    DeviceError,
    LimitError,
    RecordingError,
    ProcedureError,
    AcquisitionError,
    SubscriberOverrunError,
)


class Cancel:
    """A request from another thread that a running procedure stop (the GUI's cancel and STOP
    buttons; a signal handler could ask the same).

    The procedure stops at its next wait, within a twentieth of a second: the drive ramps
    to zero, an unfinished sweep step is marked incomplete, the file is closed with
    ``reason`` as its stop reason, and the procedure returns its result as usual.
    """

    def __init__(self) -> None:
        self._requested = threading.Event()
        self.reason = ""

    def request(self, reason: str = "cancelled") -> None:
        """Ask the procedure to stop (the first reason given is the one the file keeps)."""
        if not self._requested.is_set():
            self.reason = reason
            self._requested.set()

    @property
    def requested(self) -> bool:
        """True once a stop was asked for."""
        return self._requested.is_set()


def check_drives(limits: ShakerLimits, source: str, drives: Iterable[tuple[float, float]]) -> None:
    """LimitError, naming where ``limits`` come from, for the first (frequency_hz, amplitude_m)
    the shaker would refuse: a whole plan is checked, by the shaker's own rule, before
    anything moves."""
    try:
        for frequency_hz, amplitude_m in drives:
            ShakerAmplifier.check_settings(
                limits, frequency_hz=frequency_hz, amplitude_m=amplitude_m
            )
    except LimitError as error:
        raise LimitError(f"{error} (limits from {source})") from None


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
    """Engine, recorder and devices of one procedure: drive left at zero, file left valid.

    Without ``engine`` the session runs its own on the devices' streams.  With one (already
    running on those streams, e.g. the GUI's), the file starts when the session is made,
    and at the end the session only stops listening: the engine keeps running for its
    owner.  A failure of the drive monitor or the recorder ends the procedure, not the
    engine; ``cancel`` ends it on request.
    """

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
        progress: ProgressText | None = None,
        engine: AcquisitionEngine | None = None,
        cancel: Cancel | None = None,
    ) -> None:
        self.devices = devices
        self.progress = progress or (lambda text: None)
        self.cancel = cancel or Cancel()
        self.fs = devices.sample_rate_hz
        self.recorder = Recorder(
            path,
            devices.channel_specs(),
            metadata,
            overwrite=overwrite,
            flush_interval_s=flush_interval_s,
            compression=compression,
        )
        self._owns_engine = engine is None
        self.engine = AcquisitionEngine(devices.streams) if engine is None else engine
        self.monitor = DriveMonitor(
            devices.shaker,
            self,
            devices.config.drive_tolerance,
            where=devices.shaker.backend.description,
        )
        self._error: BaseException | None = None
        failed = self._failed = threading.Event()
        self.engine.on_failure(lambda error: failed.set())  # not self: a shared engine outlives us
        self._stats_at_start = self.engine.stats()
        self._subscription = self.engine.subscribe("recorder", privileged=True)
        self.gate = None
        source = self._subscription
        if pretrigger_s is not None:
            self.gate = PretriggerGate(
                self._subscription,
                round(pretrigger_s * self.fs),
                round(TRIGGER_SLACK_S * self.fs),
            )
            source = self.gate
        self.writer = RecorderThread(self.recorder, source, on_error=self.fail)
        self.watch = AngleWatch(self.engine.subscribe("procedure", max_items=4000), self.fs)
        self.started = 0.0
        self.stop_reason = "completed"

    def __enter__(self) -> ProcedureSession:
        self.writer.start()
        self.started = time.monotonic()
        try:
            self.monitor.check_idle()  # before anything moves: nobody else drives the table
            if self._owns_engine:  # a stream that cannot start still leaves a closed, valid file
                self.engine.start()
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
        """Raise why the procedure must stop now, if it must: a cancel request (first, so a
        STOP that also changed the drive reads as the operator's), or the failure of the
        drive monitor, the recording or acquisition."""
        if self.cancel.requested:
            raise ProcedureCancelledError(self.cancel.reason)
        if self._error is not None:
            raise self._error
        self.engine.raise_if_failed()

    def fail(self, error: BaseException) -> None:
        """End the procedure with ``error`` at its next wait (the first failure wins)."""
        if self._error is None:
            self._error = error
        self._failed.set()

    def note_drive(
        self, frequency_hz: float, amplitude_m: float, enabled: bool, source: int = COMMANDED
    ) -> DriveSetting:
        """Put a drive setting (commanded or read back) in the file and every view."""
        return self.engine.note_drive(frequency_hz, amplitude_m, enabled, source)

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

    def wait_samples(self, since_index: int, seconds: float) -> int:
        """Wait until the ``seconds`` of samples after index ``since_index`` have arrived,
        watching for failures: the rig's own clock, so that a host that falls behind (a
        loaded PC; a virtual rig slower than its speed) still records what was planned.
        Returns the index ``seconds`` on; a ProcedureError when no sample arrives for
        SAMPLES_STALL_S."""
        target = since_index + round(seconds * self.fs)
        newest = [self.engine.latest_index or since_index, time.monotonic()]

        def arrived() -> bool:
            latest = self.engine.latest_index or since_index
            now = time.monotonic()
            if latest != newest[0]:
                newest[:] = [latest, now]
            elif now - newest[1] > SAMPLES_STALL_S:
                raise ProcedureError(
                    f"no samples from the DAQ board for {SAMPLES_STALL_S:g} s (the newest is "
                    f"sample {latest}; {self.devices.board.status().message or 'no message'})"
                )
            return latest >= target

        self.wait(math.inf, until=arrived)
        return target

    def set_drive(self, frequency_hz: float, amplitude_m: float) -> None:
        """Command the drive (validated by the shaker's limits) and log it in the file; nothing
        is commanded once the procedure must stop."""
        self.check()
        shaker = self.devices.shaker
        with self.monitor.commanding(frequency_hz, amplitude_m, True):
            shaker.frequency_hz = frequency_hz
            shaker.amplitude_m = amplitude_m
            if not shaker.enabled:
                shaker.enabled = True
        self.engine.note_drive(frequency_hz, amplitude_m, True)

    def __exit__(self, kind, error, traceback) -> bool:
        """Drive to zero, file closed; a cancelled procedure goes on after its ``with``."""
        if kind is not None:
            self.stop_reason = _why_stopped(kind, error)
        self.monitor.stop()
        with contextlib.suppress(DeviceError):
            self.devices.shaker.stop()
        self.engine.note_drive(0.0, 0.0, False)
        if self.gate is not None:
            self.gate.open(self.engine.latest_index or 0)  # keep what was seen on a failure
        if self._owns_engine:
            self.engine.stop()
        else:  # the owner's engine runs on; this file ends here
            self.engine.unsubscribe(self._subscription)
            self.engine.unsubscribe(self.watch.subscription)
        self.writer.finish(self.progress)  # never close the file under a writing thread
        if self.recorder.error is not None and kind is None:
            self.stop_reason = f"error: {self.recorder.error}"
        self.recorder.close(self.stop_reason)
        return kind is not None and issubclass(kind, ProcedureCancelledError)

    def result(self, experiment: str, steps: int = 0) -> ProcedureResult:
        """Summary after the session closed (losses counted since the session began)."""
        now, before = self.engine.stats(), self._stats_at_start
        return ProcedureResult(
            path=self.recorder.path,
            experiment=experiment,
            stop_reason=self.stop_reason,
            samples_written=self.recorder.samples_written,
            samples_lost=now.samples_lost - before.samples_lost,
            lost_per_stream={
                name: lost - before.lost_per_stream.get(name, 0)
                for name, lost in now.lost_per_stream.items()
            },
            duration_s=time.monotonic() - self.started,
            steps=steps,
        )


def _why_stopped(kind: type[BaseException], error: BaseException) -> str:
    """The stop reason a file keeps for the exception that ended its procedure."""
    if issubclass(kind, KeyboardInterrupt):
        return "interrupted (Ctrl-C)"
    if issubclass(kind, ProcedureCancelledError):
        return str(error)  # the reason given with the request
    return f"error: {error}"


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
    progress: ProgressText | None = None,
    compression: str | None = "auto",
) -> ProcedureResult:
    """A plain recording: optional steady drive, then ``duration_s`` of data."""
    driven = plan.frequency_hz is not None and plan.amplitude_m is not None
    drive = {q.frequency_hz: plan.frequency_hz, q.amplitude_m: plan.amplitude_m} if driven else None
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


def _wait_with_progress(session: ProcedureSession, seconds: float, progress: ProgressText,
                        what: str):
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
    progress: ProgressText | None = None,
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
    # each step's settle and dwell, counted on the samples (the rig's own clock)
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

    def schedule(self) -> list[tuple[int, float, float, float, float]]:
        """(direction, frequency_hz, amplitude_m, settle_s, dwell_s) of every step in order
        (as :meth:`analysis.experiment_plan.ExperimentPlan.schedule`, which run_sweep runs
        too)."""
        return [(d, f, a, self.settle_s, self.dwell_s) for d, f, a in self.steps()]


def run_sweep(
    devices: RigDevices,
    path: str | Path,
    plan: SweepPlan | ExperimentPlan,
    *,
    notes: str = "",
    overwrite: bool = False,
    progress: ProgressText | None = None,
    compression: str | None = "auto",
    engine: AcquisitionEngine | None = None,
    cancel: Cancel | None = None,
) -> ProcedureResult:
    """A forced-response sweep, or the steps of an experiment plan (each with its own settle
    and dwell, direction 0); each step is marked in the file (``/sweep_steps``).

    ``engine``: one already running on the devices (the GUI's), else the sweep runs its
    own; ``cancel``: stops the sweep from another thread (see ``Cancel``).
    """
    progress = progress or (lambda text: None)
    steps = plan.schedule()
    check_drives(devices.shaker.limits, devices.config.source, [(f, a) for _, f, a, *_ in steps])
    first = steps[0]
    drive = {q.frequency_hz: first[1], q.amplitude_m: first[2]}
    meta = base_metadata(devices, FORCED.name, notes, drive, asdict(plan))
    session = ProcedureSession(
        devices,
        path,
        meta,
        overwrite=overwrite,
        progress=progress,
        compression=compression,
        engine=engine,
        cancel=cancel,
    )
    done = 0
    with session:
        for number, (direction, frequency_hz, amplitude_m, settle_s, dwell_s) in \
                enumerate(steps):
            session.set_drive(frequency_hz, amplitude_m)
            settle_start = session.engine.latest_index or 0
            arrow = {1: "up", -1: "down"}.get(direction, "planned")
            session.engine.mark_step(
                StepBegun(number, len(steps), direction, frequency_hz, amplitude_m, settle_start)
            )
            progress(
                f"step {number + 1}/{len(steps)} {arrow}: {frequency_hz:g} Hz, "
                f"{amplitude_m * 1e3:g} mm, settling {settle_s:g} s"
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
                dwell_start = session.wait_samples(settle_start, settle_s)
                mark = replace(mark, dwell_start_index=dwell_start, dwell_end_index=dwell_start)
                progress(f"step {number + 1}/{len(steps)} {arrow}: dwell {dwell_s:g} s")
                end = session.wait_samples(dwell_start, dwell_s)
            except BaseException:
                end = session.engine.latest_index or mark.dwell_start_index
                session.engine.mark_step(replace(mark, dwell_end_index=end))
                raise
            session.engine.mark_step(replace(mark, dwell_end_index=end, complete=True))
            done += 1
    return session.result(FORCED.name, steps=done)
