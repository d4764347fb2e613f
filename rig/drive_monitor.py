"""The amplifier read back before and during a run: its actual drive against the asked drive.

Another Modbus client, the front panel or a fault can change what the table does; the
host only knows by reading the amplifier.  :class:`DriveMonitor` checks the amplifier
is idle before a run, then polls its setpoints and measured output, writes every
reading into the recording (``/drive`` rows with source 1, measured) and fails the run
when the drive is not what was asked (setpoints changed by someone else at once, the
measured output once it had ``settle_s`` to follow).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

from drivers.interfaces import DeviceError
from drivers.shaker_device import MeasuredDrive, Setpoints
from rig.config import DriveTolerance
from rig.events import MEASURED
from rig.logs import FILE_ONLY

POLL_PERIOD_S = 0.25
SETPOINT_HZ = 0.0015  # the registers hold whole mHz and um: anything further was not ours
SETPOINT_M = 1.5e-6

log = logging.getLogger("impact_rig.drive")


class DriveMismatchError(DeviceError):
    """The amplifier's actual drive is not the drive the host asked for."""


class Amplifier(Protocol):
    """What the monitor reads (``drivers.shaker.ShakerAmplifier``)."""

    def measured(self) -> MeasuredDrive: ...

    def setpoints(self) -> Setpoints: ...


class DriveLog(Protocol):
    """Where readings go and failures are reported (``rig.engine.AcquisitionEngine``)."""

    def note_drive(
        self, frequency_hz: float, amplitude_m: float, enabled: bool, source: int = ...
    ) -> object: ...

    def fail(self, error: BaseException) -> None: ...


@dataclass(frozen=True)
class AskedDrive:
    """The drive the host asked for, and when."""

    frequency_hz: float
    amplitude_m: float
    enabled: bool
    since_s: float  # time.monotonic() of the request


def _describe(frequency_hz: float, amplitude_m: float, enabled: bool) -> str:
    return f"{frequency_hz:g} Hz, {amplitude_m * 1e3:g} mm, {'on' if enabled else 'off'}"


class DriveMonitor:
    """Compares the amplifier's read-back drive with the asked drive, in its own thread."""

    def __init__(
        self,
        amplifier: Amplifier,
        drive_log: DriveLog,
        tolerance: DriveTolerance,
        *,
        period_s: float = POLL_PERIOD_S,
        where: str = "the shaker amplifier",
    ) -> None:
        self.amplifier = amplifier
        self.drive_log = drive_log
        self.tolerance = tolerance
        self.period_s = period_s
        self.where = where
        self._asked = AskedDrive(0.0, 0.0, False, time.monotonic())
        self._command_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def check_idle(self) -> None:
        """Before a run: the amplifier must be off and still (DriveMismatchError otherwise)."""
        held, out = self.amplifier.setpoints(), self.amplifier.measured()
        if held.enabled or out.enabled or out.amplitude_m > self.tolerance.amplitude_floor_m:
            raise DriveMismatchError(
                f"{self.where} is already driving before the run (set: "
                f"{_describe(held.frequency_hz, held.amplitude_m, held.enabled)}; measured: "
                f"{_describe(out.frequency_hz, out.amplitude_m, out.enabled)}); another client "
                "or its front panel started it: stop it, then start the run again"
            )

    @contextlib.contextmanager
    def commanding(self, frequency_hz: float, amplitude_m: float, enabled: bool) -> Iterator[None]:
        """Wrap the host's writes of a new drive: no reading falls between two of them."""
        with self._command_lock:
            yield
            self._asked = AskedDrive(frequency_hz, amplitude_m, enabled, time.monotonic())

    def start(self) -> None:
        """Poll in a background thread until ``stop``."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="drive-monitor", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop polling (waits for the thread)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None

    def check_once(self) -> None:
        """Read the amplifier, log the reading, raise DriveMismatchError when it disagrees."""
        with self._command_lock:
            held, out = self.amplifier.setpoints(), self.amplifier.measured()
            asked = self._asked
        self.drive_log.note_drive(out.frequency_hz, out.amplitude_m, out.enabled, MEASURED)
        problem = self.disagreement(asked, held, out, time.monotonic())
        if problem:
            raise DriveMismatchError(f"{self.where}: {problem}; the run was stopped")

    def disagreement(
        self, asked: AskedDrive, held: Setpoints, out: MeasuredDrive, now_s: float
    ) -> str:
        """Why the read-back drive is not the asked one ('' when it is)."""
        if out.faults:
            return f"faults latched ({', '.join(out.faults)})"
        asked_text = _describe(asked.frequency_hz, asked.amplitude_m, asked.enabled)
        if (
            held.enabled != asked.enabled
            or (asked.enabled and abs(held.frequency_hz - asked.frequency_hz) > SETPOINT_HZ)
            or (asked.enabled and abs(held.amplitude_m - asked.amplitude_m) > SETPOINT_M)
        ):
            return (
                f"its setpoints were changed to "
                f"{_describe(held.frequency_hz, held.amplitude_m, held.enabled)} (asked: "
                f"{asked_text}) by another client or its front panel"
            )
        if now_s - asked.since_s < self.tolerance.settle_s:
            return ""
        target_m = asked.amplitude_m if asked.enabled else 0.0
        amplitude_limit = max(
            self.tolerance.amplitude_fraction * target_m, self.tolerance.amplitude_floor_m
        )
        frequency_off = asked.enabled and (
            abs(out.frequency_hz - asked.frequency_hz) > self.tolerance.frequency_hz
        )
        if frequency_off or abs(out.amplitude_m - target_m) > amplitude_limit:
            return (
                f"it measures {_describe(out.frequency_hz, out.amplitude_m, out.enabled)} "
                f"{self.tolerance.settle_s:g} s after the host asked for {asked_text} "
                f"(limits: {self.tolerance.frequency_hz:g} Hz, {amplitude_limit * 1e3:g} mm)"
            )
        return ""

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            try:
                self.check_once()
            except DeviceError as error:  # a mismatch, or the link failed: the run stops
                log.error("%s", error, extra=FILE_ONLY)  # the run stops and says it
                self.drive_log.fail(error)
                return
