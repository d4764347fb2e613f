"""What every drive of the shake table does the same way, whatever it talks.

Two drives implement the shaker's interface: the amplifier's own controller over
Modbus registers (:class:`drivers.shaker.ShakerAmplifier`) and a bench function
generator over SCPI (:class:`drivers.scpi_shaker.ScpiShaker`).  Both are a
:class:`ShakerDevice`: the ``with`` block, the link's state, ``status``, the waits
on ``measured()`` and the guarded exchange ``_io`` (refused before connect or after
a link failure; any DeviceError makes the drive safe) live here once.  Each drive
says how it connects, closes, reads its output and what a failure does.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self, TypeVar

from drivers.interfaces import ActuatorStatus, DeviceError

T = TypeVar("T")


@dataclass(frozen=True)
class MeasuredDrive:
    """The drive's measurement (or read-back) of its own output, and its state bits."""

    frequency_hz: float
    amplitude_m: float
    enabled: bool
    ramping: bool
    at_zero: bool
    faults: tuple[str, ...]


@dataclass(frozen=True)
class Setpoints:
    """What the drive holds: what it is asked to do, by the host or anyone else."""

    frequency_hz: float
    amplitude_m: float
    ramp_rate_m_s: float
    enabled: bool


class ShakerDevice:
    """The part of a shaker drive that does not depend on its protocol.

    A subclass sets ``name``, ``_connected``, ``_link_failure`` and ``_io_lock`` in its
    ``__init__``, and gives ``connect``, ``close``, ``measured`` and ``_failed``.
    """

    name: str
    _connected: bool
    _link_failure: DeviceError | None
    _io_lock: threading.RLock

    def connect(self) -> Self:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def measured(self) -> MeasuredDrive:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        """True between connect() and close(), while the link works."""
        return self._connected and self._link_failure is None

    @property
    def reconnecting(self) -> bool:
        """The link failed and the drive is trying to reach the device again (if it can)."""
        return False

    def status(self) -> ActuatorStatus:
        """Connection, enable, measured output and faults; never raises."""
        if not self._connected:
            return ActuatorStatus(connected=False, enabled=False)
        if self._link_failure is not None:
            again = "; reconnecting" if self.reconnecting else ""
            return ActuatorStatus(
                False, False, faults=(f"communication lost: {self._link_failure}{again}",)
            )
        try:
            m = self.measured()
        except DeviceError as error:
            return ActuatorStatus(False, False, faults=(f"communication lost: {error}",))
        return ActuatorStatus(
            connected=True,
            enabled=m.enabled,
            measured={"frequency_hz": m.frequency_hz, "amplitude_m": m.amplitude_m},
            faults=m.faults,
        )

    def wait_until(
        self,
        condition: Callable[[MeasuredDrive], bool],
        timeout_s: float,
        what: str,
        poll_s: float = 0.02,
    ) -> MeasuredDrive:
        """Poll ``measured()`` until ``condition`` holds; DeviceError after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while True:
            m = self.measured()
            if condition(m):
                return m
            if time.monotonic() > deadline:
                raise DeviceError(
                    f"{self.name}: waited {timeout_s} s but not {what} ({self._holds(m)})"
                )
            time.sleep(poll_s)

    def wait_settled(self, timeout_s: float = 10.0) -> MeasuredDrive:
        """Wait until the output stopped ramping (the amplifier's ramp, or the host's)."""
        return self.wait_until(lambda m: not m.ramping, timeout_s, "settled")

    def _holds(self, m: MeasuredDrive) -> str:
        """Where the output is, for a wait that timed out."""
        return (
            f"measured {m.amplitude_m:.6g} m at {m.frequency_hz:.6g} Hz, "
            f"faults: {', '.join(m.faults) or 'none'}"
        )

    def _io(self, what: str, operation: Callable[..., T], *args: Any) -> T:
        """Run one exchange; on a DeviceError make the drive safe and raise what ``_failed``
        returns (the error itself, or one that says more)."""
        if not self._connected:
            raise DeviceError(f"{self.name}: not connected (call connect() first)")
        if self._link_failure is not None:
            raise DeviceError(
                f"{self.name}: communication failed earlier ({self._link_failure}); "
                "close and reconnect"
            )
        try:
            with self._io_lock:
                return operation(*args)
        except DeviceError as error:
            raised = self._failed(what, error)
            if raised is error:
                raise
            raise raised from None

    def _failed(self, what: str, error: DeviceError) -> DeviceError:
        """Called by ``_io`` on ``error`` during ``what``: note a lost link, make the drive
        safe, and return the error to raise."""
        raise NotImplementedError
