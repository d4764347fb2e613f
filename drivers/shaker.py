"""The shaker amplifier as a device: settings declared once with unit, limits and docstring.

How it talks is a backend passed in (Modbus TCP/RTU in :mod:`drivers.modbus_shaker`;
the tests add one straight into the emulator's firmware); every backend
moves raw registers of docs/amplifier_registers.md and raises DeviceError on
failure.  Safety lives here: a value outside the configured limits raises
LimitError before any byte is sent; a background thread writes the heartbeat;
any communication error, ``close``, leaving a ``with`` block or interpreter exit
ramps the drive to zero.  With ``reconnect=True`` a lost link is reached again in the
heartbeat's thread; the drive is commanded off before the link is trusted again (what it
did meanwhile is unknown: the amplifier's watchdog stopped it), and stays off until asked.
"""

from __future__ import annotations

import atexit
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from drivers.amplifier_registers import (
    DEVICE_MAX_AMPLITUDE_UM,
    DEVICE_MAX_FREQUENCY_MHZ,
    DEVICE_MAX_RAMP_RATE_UM_S,
    MAP_VERSION,
    MODEL_CODE,
    WATCHDOG_MAX_MS,
    WATCHDOG_MIN_MS,
    Command,
    Holding,
    Input,
    Status,
    fault_words,
    join_u32,
    split_u32,
)
from drivers.interfaces import DeviceError, WrongDeviceError
from drivers.limits import ShakerLimits
from drivers.shaker_device import MeasuredDrive, Setpoints, ShakerDevice

# Exception codes that refuse one request on a working link (illegal function, address,
# value).  Any other reply (device failure, busy ...) means the controller cannot be
# trusted: the host stops its heartbeat so that the amplifier's watchdog stops the drive.
REFUSALS = (0x01, 0x02, 0x03)


class CommandRefusedError(DeviceError):
    """The amplifier answered with a Modbus exception; ``code`` is the exception code."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class RegisterBackend(Protocol):
    """Raw register access to the amplifier; every failure is a DeviceError."""

    description: str  # where the device is, for messages ("Modbus TCP 127.0.0.1:502")

    def open(self) -> None:
        """Connect; DeviceNotFoundError when the port or host is not there."""
        ...

    def close(self) -> None:
        """Release the connection; safe to call more than once."""
        ...

    def read_input_registers(self, address: int, count: int) -> list[int]:
        """FC4: ``count`` input registers from ``address``."""
        ...

    def read_holding_registers(self, address: int, count: int) -> list[int]:
        """FC3: ``count`` holding registers from ``address``."""
        ...

    def write_registers(self, address: int, values: Sequence[int]) -> None:
        """FC16: ``values`` into consecutive holding registers from ``address``, in one request."""
        ...


@dataclass(frozen=True)
class AmplifierIdentity:
    """What the amplifier says it is."""

    model_code: int
    firmware: str
    map_version: int


class RegisterSetting:
    """A setpoint held in holding registers: unit, scaling and limits declared in one place.

    Reading returns the amplifier's current setpoint in SI units; assigning checks
    the configured limits (LimitError, nothing sent) and then writes the scaled
    integer in one request.
    """

    def __init__(
        self,
        register: Holding,
        *,
        words: int,
        unit: str,
        counts_per_unit: float,
        limits: Callable[[ShakerLimits], tuple[float, float]],
        doc: str,
    ) -> None:
        self.register = register
        self.words = words
        self.unit = unit
        self.counts_per_unit = counts_per_unit
        self.limits = limits
        self.__doc__ = f"{doc} [{unit}]"
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, device: ShakerAmplifier | None, owner: type) -> Any:
        if device is None:
            return self
        regs = device._io(
            f"read {self.name}",
            device.backend.read_holding_registers,
            int(self.register),
            self.words,
        )
        counts = join_u32(*regs) if self.words == 2 else regs[0]
        return counts / self.counts_per_unit

    def check(self, limits: ShakerLimits, value: float) -> float:
        """``value`` as float when ``limits`` allow it, else LimitError (nothing is sent)."""
        low, high = self.limits(limits)
        return limits.check(self.name, value, low, high, self.unit)

    def __set__(self, device: ShakerAmplifier, value: float) -> None:
        checked = self.check(device.limits, value)
        counts = round(checked * self.counts_per_unit)
        regs = split_u32(counts) if self.words == 2 else [counts]
        device._io(f"write {self.name}", device.backend.write_registers, int(self.register), regs)


class ShakerAmplifier(ShakerDevice):
    """The shake table's amplifier: setpoints, measured output, faults, safe stop.

    Use as a context manager (or call ``connect`` and ``close``)::

        with ShakerAmplifier(ModbusTcpBackend("127.0.0.1", 5020), limits) as shaker:
            shaker.frequency_hz = 10.0
            shaker.amplitude_m = 1.0e-3
            shaker.enabled = True
    """

    frequency_hz = RegisterSetting(
        Holding.FREQUENCY_MHZ_HI,
        words=2,
        unit="Hz",
        counts_per_unit=1000.0,
        limits=lambda lim: (lim.min_frequency_hz, lim.max_frequency_hz),
        doc="Drive frequency setpoint (sent in mHz); the output slews to it.",
    )
    amplitude_m = RegisterSetting(
        Holding.AMPLITUDE_UM,
        words=1,
        unit="m",
        counts_per_unit=1e6,
        limits=lambda lim: (0.0, lim.max_amplitude_m),
        doc="Table displacement amplitude setpoint (sent in micrometres).",
    )
    ramp_rate_m_s = RegisterSetting(
        Holding.RAMP_RATE_UM_S,
        words=1,
        unit="m/s",
        counts_per_unit=1e6,
        limits=lambda lim: (lim.min_ramp_rate_m_s, lim.max_ramp_rate_m_s),
        doc="How fast the output amplitude may change (sent in micrometres per second).",
    )

    def __init__(
        self,
        backend: RegisterBackend,
        limits: ShakerLimits | None = None,
        *,
        watchdog_s: float = 1.0,
        heartbeat_period_s: float | None = None,
        expected_model_code: int = MODEL_CODE,
        name: str = "shaker amplifier",
        reconnect: bool = False,
    ) -> None:
        if not WATCHDOG_MIN_MS <= watchdog_s * 1000 <= WATCHDOG_MAX_MS:
            raise ValueError(
                f"watchdog_s = {watchdog_s}: the amplifier accepts "
                f"{WATCHDOG_MIN_MS / 1000}..{WATCHDOG_MAX_MS / 1000} s"
            )
        self.backend = backend
        self.limits = limits or ShakerLimits()
        self.watchdog_s = float(watchdog_s)
        self.heartbeat_period_s = heartbeat_period_s or self.watchdog_s / 5.0
        if not 0 < self.heartbeat_period_s < self.watchdog_s:
            raise ValueError(
                f"heartbeat_period_s = {heartbeat_period_s} must be shorter than the watchdog "
                f"timeout {self.watchdog_s} s"
            )
        self.expected_model_code = expected_model_code
        self.name = name
        self.reconnect = reconnect
        self.reconnections = 0  # times a lost link was reached again
        self._io_lock = threading.RLock()
        self._connected = False
        self._link_failure: DeviceError | None = None
        self._heartbeat_stop = threading.Event()
        self._heartbeat_thread: threading.Thread | None = None
        self.identity: AmplifierIdentity | None = None

    @classmethod
    def check_settings(cls, limits: ShakerLimits, **settings: float) -> None:
        """LimitError for the first of ``settings`` (``name=value``) that ``limits`` forbid.

        The very check assigning the setting makes, without a device: a procedure refuses
        a whole plan with it before anything is sent, and says what the shaker would say.
        """
        for name, value in settings.items():
            setting = cls.__dict__.get(name)
            if not isinstance(setting, RegisterSetting):
                raise TypeError(f"{name!r} is not a setting of the shaker amplifier")
            setting.check(limits, value)

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> ShakerAmplifier:
        """Open the backend, check the identity, set the watchdog, start the heartbeat."""
        if self._connected:
            return self
        self.backend.open()
        try:
            self._identify_and_arm()
        except DeviceError:
            self.backend.close()
            raise
        self._connected = True
        self._link_failure = None
        self._heartbeat_stop.clear()
        self._heartbeat_thread = threading.Thread(
            target=self._heartbeat, name=f"{self.name} heartbeat", daemon=True
        )
        self._heartbeat_thread.start()
        atexit.register(self.close)
        return self

    def _identify_and_arm(self) -> None:
        """Check the identity and set the watchdog (on a freshly opened backend)."""
        regs = self.backend.read_input_registers(int(Input.MODEL_CODE), 3)
        model, firmware, map_version = regs
        if model != self.expected_model_code or map_version != MAP_VERSION:
            raise WrongDeviceError(
                f"{self.backend.description} answered model code 0x{model:04X}, register "
                f"map {map_version}; expected the shaker amplifier 0x"
                f"{self.expected_model_code:04X}, map {MAP_VERSION} "
                "(check the address, port and device id)"
            )
        version = f"{firmware >> 8}.{firmware & 0xFF}"
        self.identity = AmplifierIdentity(model, version, map_version)
        self.backend.write_registers(int(Holding.WATCHDOG_MS), [round(self.watchdog_s * 1000)])

    @property
    def reconnecting(self) -> bool:
        """The link failed and the driver is trying to reach the amplifier again."""
        return self._connected and self.reconnect and self._link_failure is not None

    def close(self) -> None:
        """Ramp the drive to zero (best effort), stop the heartbeat, release the connection."""
        if not self._connected:
            return
        if self._link_failure is None:
            self._make_safe()
        self._heartbeat_stop.set()
        beat = self._heartbeat_thread
        if beat is not None and beat is not threading.current_thread():
            beat.join(5.0)
        with self._io_lock:
            self.backend.close()
            self._connected = False
        atexit.unregister(self.close)

    # ------------------------------------------------------------------ commands

    @property
    def enabled(self) -> bool:
        """Drive on (True) or ramping to / resting at zero (False)."""
        (value,) = self._io(
            "read enable", self.backend.read_holding_registers, int(Holding.ENABLE), 1
        )
        return bool(value)

    @enabled.setter
    def enabled(self, on: bool) -> None:
        if not isinstance(on, bool):
            raise TypeError(f"enabled = {on!r}: expected True or False")
        if on:
            self._io("enable", self.backend.write_registers, int(Holding.ENABLE), [1])
        else:
            self.stop()

    def stop(self, wait_s: float = 0.0) -> None:
        """Amplitude setpoint 0 and drive off: the output ramps to zero.

        With ``wait_s > 0``, also wait (at most that long) until the measured
        amplitude is zero.  Safe to call at any time and more than once.
        """
        self._io("write amplitude_m", self.backend.write_registers, int(Holding.AMPLITUDE_UM), [0])
        self._io("disable", self.backend.write_registers, int(Holding.ENABLE), [0])
        if wait_s > 0:
            self.wait_until(lambda m: m.at_zero, wait_s, "the output reached zero")

    def clear_faults(self) -> None:
        """Clear latched faults whose cause is gone (the drive stays off until enabled)."""
        self._io(
            "clear faults",
            self.backend.write_registers,
            int(Holding.COMMAND),
            [int(Command.CLEAR_FAULTS)],
        )

    # ------------------------------------------------------------------ readings

    def measured(self) -> MeasuredDrive:
        """Measured frequency and amplitude, state bits and faults, in one request."""
        regs = self._io(
            "read measurements",
            self.backend.read_input_registers,
            int(Input.STATUS),
            int(Input.MEASURED_AMPLITUDE_UM) - int(Input.STATUS) + 1,
        )
        status = Status(regs[0])
        frequency_mhz = join_u32(regs[2], regs[3])
        if frequency_mhz > DEVICE_MAX_FREQUENCY_MHZ or regs[4] > DEVICE_MAX_AMPLITUDE_UM:
            raise self._garbled(
                "read measurements", f"a measured drive of {frequency_mhz / 1000:g} Hz, "
                f"{regs[4] / 1000:g} mm"
            )
        return MeasuredDrive(
            frequency_hz=frequency_mhz / 1000.0,
            amplitude_m=regs[4] * 1e-6,
            enabled=bool(status & Status.ENABLED),
            ramping=bool(status & Status.RAMPING),
            at_zero=bool(status & Status.AT_ZERO),
            faults=fault_words(regs[1]),
        )

    def setpoints(self) -> Setpoints:
        """The setpoints the amplifier holds now (whoever wrote them), in one request."""
        regs = self._io(
            "read setpoints",
            self.backend.read_holding_registers,
            int(Holding.FREQUENCY_MHZ_HI),
            int(Holding.ENABLE) - int(Holding.FREQUENCY_MHZ_HI) + 1,
        )
        frequency_mhz = join_u32(regs[0], regs[1])
        if (
            frequency_mhz > DEVICE_MAX_FREQUENCY_MHZ
            or regs[2] > DEVICE_MAX_AMPLITUDE_UM
            or regs[3] > DEVICE_MAX_RAMP_RATE_UM_S
            or regs[4] > 1
        ):
            raise self._garbled(
                "read setpoints", f"setpoints of {frequency_mhz / 1000:g} Hz, "
                f"{regs[2] / 1000:g} mm, ramp {regs[3] / 1000:g} mm/s, enable {regs[4]}"
            )
        return Setpoints(
            frequency_hz=frequency_mhz / 1000.0,
            amplitude_m=regs[2] * 1e-6,
            ramp_rate_m_s=regs[3] * 1e-6,
            enabled=bool(regs[4]),
        )

    def faults(self) -> tuple[str, ...]:
        """Plain-word names of the latched faults (empty when healthy)."""
        (bits,) = self._io("read faults", self.backend.read_input_registers, int(Input.FAULTS), 1)
        return fault_words(bits)

    # ------------------------------------------------------------------ internals

    def _garbled(self, what: str, words: str) -> DeviceError:
        """A reply no amplifier gives (beyond its own ranges): garbled on the way, so the
        link is not trusted (``_failed``), and nothing of it is passed on."""
        return self._failed(
            what,
            DeviceError(
                f"{self.backend.description} reported {words}, beyond the amplifier's own "
                "range: a garbled reply"
            ),
        )

    def _failed(self, what: str, error: DeviceError) -> DeviceError:
        """A refusal leaves the link trusted; any other failure stops the heartbeat (the
        amplifier's watchdog backs us up).  Either way the drive is commanded to zero."""
        if not (isinstance(error, CommandRefusedError) and error.code in REFUSALS):
            self._link_failure = error  # the heartbeat stops: the amplifier's watchdog backs us up
            if not self.reconnect:
                self._heartbeat_stop.set()
        self._make_safe()
        error.add_note(
            f"{self.name}: '{what}' failed; the drive was commanded to zero (if the link "
            "is down, the amplifier's watchdog stops it)"
        )
        return error

    def _make_safe(self) -> None:
        """Best effort: amplitude 0, drive off; errors swallowed (the watchdog is the backup)."""
        for register in (Holding.AMPLITUDE_UM, Holding.ENABLE):
            try:
                with self._io_lock:
                    self.backend.write_registers(int(register), [0])
            except DeviceError:
                if self._link_failure is not None:
                    return  # the link is down: do not wait for a second timeout

    def _heartbeat(self) -> None:
        counter = 0
        while not self._heartbeat_stop.wait(self.heartbeat_period_s):
            if self._link_failure is not None:  # no heartbeat: the watchdog stops the drive
                if not self.reconnect:
                    return
                self._relink()
                continue
            counter = (counter + 1) & 0xFFFF
            try:
                with self._io_lock:
                    self.backend.write_registers(int(Holding.HEARTBEAT), [counter])
            except DeviceError as error:
                self._link_failure = error
                self._make_safe()
                if not self.reconnect:
                    return

    def _relink(self) -> None:
        """One try at reaching the amplifier again: reopen, identify, arm the watchdog and
        command the drive off; only then is the link trusted again."""
        with self._io_lock:
            try:
                self.backend.close()
                self.backend.open()
                self._identify_and_arm()
                for register in (Holding.AMPLITUDE_UM, Holding.ENABLE):
                    self.backend.write_registers(int(register), [0])
            except DeviceError:
                return  # still away (or something else answers): try again next beat
            self._link_failure = None
            self.reconnections += 1
