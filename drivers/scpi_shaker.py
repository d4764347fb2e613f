"""The shake table driven by a bench function generator over SCPI (pyvisa): limits, ramps, stop.

Wiring: generator output -> power amplifier input -> shaker.  The table's displacement
amplitude (m) is the generator's sine amplitude (V peak) times the amplifier gain
``gain_m_per_v`` (m of table amplitude per V of generator amplitude, calibrated on the
rig); the generator is programmed in volts peak-to-peak, so ``Vpp = 2 * amplitude_m /
gain_m_per_v``.

The commands are the SOURce/OUTPut subsystem of the Keysight 33500B and the Rigol
DG800/DG1000Z (``SOUR1:FREQ``, ``SOUR1:VOLT`` with ``VOLT:UNIT VPP``, ``OUTP1 ON|OFF``,
``SYST:ERR?``, ``*IDN?``, ``*OPC?``), sent through pyvisa with the pure-Python
pyvisa-py backend: ``TCPIP::host::5025::SOCKET`` (or a USB-TMC / serial resource).

The rules, the same as the Modbus amplifier's (:class:`drivers.shaker.ShakerAmplifier`):

* a setting outside the configured :class:`~drivers.limits.ShakerLimits` (or beyond
  ``max_output_vpp``) raises LimitError before any byte is sent;
* every setting is followed by ``*OPC?``, the error queue (``SYST:ERR?``) and a read-back;
  an error entry or a read-back that differs raises a one-line DeviceError naming the
  setting, and the output is turned off;
* the amplitude moves at ``ramp_rate_m_s``: the host steps it (a generator has no
  ramp of its own), also when the output goes on and when it is stopped;
* the output is turned off on every exit path: ``stop``, ``close``, leaving a ``with``
  block, any communication error and (best effort) interpreter exit.

A generator has no watchdog: if the host dies without closing, its output stays on.
docs/scpi_generator.md says what a lab must add (an interlock, or a burst mode).
"""

from __future__ import annotations

import atexit
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import pyvisa
from pyvisa import constants as visa_constants
from pyvisa.errors import VisaIOError

from drivers.amplifier_registers import DEFAULT_RAMP_RATE_UM_S
from drivers.interfaces import (
    DeviceError,
    DeviceNotFoundError,
    LimitError,
    WrongDeviceError,
)
from drivers.limits import ShakerLimits
from drivers.shaker import ShakerAmplifier
from drivers.shaker_device import MeasuredDrive, Setpoints, ShakerDevice

T = TypeVar("T")

log = logging.getLogger("impact_rig.shaker")

# A generator cannot output 0 V: "amplitude 0" is sent as this (the 33500B's smallest into
# High Z), and the output goes off on stop.
MIN_VPP = 0.002
# Resolution the generators hold settings to (33500B/DG1000Z: 1 uHz, 0.1 mV); the read-back
# must agree with what was sent within half of it, plus a relative part for their 4-digit
# amplitude display at large values.
FREQUENCY_TOLERANCE_HZ = 1e-6
VPP_DECIMALS = 4  # amplitudes are sent to 0.1 mV
VPP_RESOLUTION = 10.0**-VPP_DECIMALS
AMPLITUDE_TOLERANCE_VPP = 1e-4
AMPLITUDE_TOLERANCE_FRACTION = 1e-3
RAMP_STEP_S = 0.05  # the host's amplitude steps during a ramp
MAX_ERRORS_READ = 20  # SYST:ERR? until "No error", at most the queue's length


class ScpiLinkError(DeviceError):
    """The generator did not answer or the connection failed: the link cannot be trusted."""


class InstrumentError(DeviceError):
    """The generator's error queue held an entry after a command."""


class SettingNotConfirmedError(DeviceError):
    """The generator holds another value than the one sent (clipped, refused, or changed)."""


class RampInterruptedError(DeviceError):
    """An amplitude ramp was cut short by ``stop`` or ``close`` from another thread."""


@dataclass(frozen=True)
class GeneratorIdentity:
    """What ``*IDN?`` answered."""

    manufacturer: str
    model: str
    serial: str
    firmware: str


class ScpiLink:
    """One SCPI instrument through pyvisa (pyvisa-py backend): write, query, nothing else.

    Every failure is a DeviceError naming the resource and the command: a timeout or a
    lost connection is a :class:`ScpiLinkError`; nothing listening, DeviceNotFoundError.
    """

    def __init__(self, resource: str, *, timeout_s: float = 1.0, visa_library: str = "@py") -> None:
        if not 0 < timeout_s <= 60:
            raise ValueError(f"timeout_s = {timeout_s}: expected (0, 60] s")
        self.resource = resource
        self.timeout_s = float(timeout_s)
        self.visa_library = visa_library
        self.description = f"SCPI generator at {resource}"
        self._manager: pyvisa.ResourceManager | None = None
        self._instrument: Any = None

    def open(self) -> None:
        """Open the resource; DeviceNotFoundError when it cannot be opened."""
        timeout_ms = round(self.timeout_s * 1000)
        try:
            self._manager = pyvisa.ResourceManager(self.visa_library)
            self._instrument = self._manager.open_resource(
                self.resource,
                read_termination="\n",
                write_termination="\n",
                timeout=timeout_ms,
                open_timeout=timeout_ms,
            )
        except (VisaIOError, ValueError, OSError) as error:
            self.close()
            raise DeviceNotFoundError(
                f"{self.description}: cannot open ({_one_line(error)}); is the generator on "
                "and the resource string right?"
            ) from None

    def close(self) -> None:
        """Release the resource; safe to call more than once."""
        instrument, self._instrument = self._instrument, None
        manager, self._manager = self._manager, None
        for item in (instrument, manager):
            if item is not None:
                try:
                    item.close()
                except (VisaIOError, OSError) as error:
                    log.debug("%s: close: %s", self.description, error)

    def write(self, command: str) -> None:
        """Send one command line."""
        self._call(command, lambda: self._instrument.write(command))

    def query(self, command: str) -> str:
        """Send one query line and return its answer (without the terminator)."""
        return self._call(command, lambda: str(self._instrument.query(command)).strip())

    def _call(self, command: str, operation: Callable[[], T]) -> T:
        if self._instrument is None:
            raise ScpiLinkError(f"{self.description}: not open")
        try:
            return operation()
        except VisaIOError as error:
            if error.error_code == visa_constants.StatusCode.error_timeout:
                raise ScpiLinkError(
                    f"{self.description}: no answer to '{command}' within {self.timeout_s:g} s"
                ) from None
            raise ScpiLinkError(
                f"{self.description}: '{command}' failed ({_one_line(error)})"
            ) from None
        except ConnectionRefusedError:
            raise DeviceNotFoundError(
                f"{self.description}: connection refused; is the generator on, and is the "
                "port (usually 5025) right?"
            ) from None
        except (OSError, ValueError) as error:  # reset, broken pipe, closed session
            raise ScpiLinkError(
                f"{self.description}: connection lost during '{command}' ({_one_line(error)})"
            ) from None


class ScpiShaker(ShakerDevice):
    """The shake table driven by a function generator: the ShakerAmplifier's interface over SCPI.

    Use as a context manager (or call ``connect`` and ``close``)::

        link = ScpiLink("TCPIP::192.168.1.20::5025::SOCKET", timeout_s=1.0)
        with ScpiShaker(link, limits, gain_m_per_v=1.0e-3) as shaker:
            shaker.frequency_hz = 10.0
            shaker.amplitude_m = 1.0e-3
            shaker.enabled = True   # output on at the smallest amplitude, then ramped up

    ``measured()`` is the generator's own read-back, not a measurement of the table: the
    laser channel measures the table.
    """

    def __init__(
        self,
        backend: ScpiLink,
        limits: ShakerLimits | None = None,
        *,
        gain_m_per_v: float,
        max_output_vpp: float = 10.0,
        channel: int = 1,
        ramp_step_s: float = RAMP_STEP_S,
        name: str = "shaker generator",
    ) -> None:
        if not (math.isfinite(gain_m_per_v) and gain_m_per_v > 0):
            raise ValueError(f"gain_m_per_v = {gain_m_per_v!r}: expected a number > 0")
        if not (math.isfinite(max_output_vpp) and max_output_vpp > MIN_VPP):
            raise ValueError(f"max_output_vpp = {max_output_vpp!r}: expected > {MIN_VPP} V")
        if channel not in (1, 2):
            raise ValueError(f"channel = {channel!r}: expected 1 or 2")
        if not 0 < ramp_step_s <= 1:
            raise ValueError(f"ramp_step_s = {ramp_step_s!r}: expected (0, 1] s")
        self.backend = backend
        self.limits = limits or ShakerLimits()
        self.gain_m_per_v = float(gain_m_per_v)
        self.max_output_vpp = float(max_output_vpp)
        self.channel = channel
        self.ramp_step_s = float(ramp_step_s)
        self.name = name
        self.identity: GeneratorIdentity | None = None
        self._ramp_rate_m_s = min(
            max(DEFAULT_RAMP_RATE_UM_S * 1e-6, self.limits.min_ramp_rate_m_s),
            self.limits.max_ramp_rate_m_s,
        )
        self._target_m = 0.0  # the amplitude asked for
        self._vpp = MIN_VPP  # the amplitude the generator confirmed last
        self._output = False  # the output state the generator confirmed last
        self._ramping = False
        self._ramp_generation = 0  # stop/close bump it: a running ramp ends at its next step
        self._wake = threading.Event()
        self._io_lock = threading.RLock()  # one command/answer exchange at a time
        self._command_lock = threading.RLock()  # one setting sequence (a ramp) at a time
        self._connected = False
        self._link_failure: DeviceError | None = None

    @classmethod
    def check_settings(cls, limits: ShakerLimits, **settings: float) -> None:
        """LimitError for the first of ``settings`` that ``limits`` forbid: the Modbus
        amplifier's very rule (the volts ceiling is checked when the value is set)."""
        ShakerAmplifier.check_settings(limits, **settings)

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> ScpiShaker:
        """Open the link, check ``*IDN?``, refuse a generator whose output is already on,
        then set a sine, Vpp units, no offset and the smallest amplitude (each confirmed)."""
        if self._connected:
            return self
        self.backend.open()
        try:
            self.identity = _identity(self.backend, self.backend.query("*IDN?"))
            if _is_on(self.backend.query(f"OUTP{self.channel}?")):
                raise DeviceError(
                    f"{self.backend.description}: output {self.channel} is already on (another "
                    "client, its front panel, or a host that died left it on); turn it off at "
                    "the generator, then connect again"
                )
            self._done("*CLS")  # errors queued before us are not ours
            self._connected, self._link_failure = True, None
            src = f"SOUR{self.channel}"
            self._confirm_word("waveform", f"{src}:FUNC SIN", f"{src}:FUNC?", "SIN")
            self._confirm_word("amplitude unit", f"{src}:VOLT:UNIT VPP", f"{src}:VOLT:UNIT?", "VPP")
            self._confirm_number("offset", f"{src}:VOLT:OFFS", 0.0, "V", 1e-3)
            self._send_vpp(MIN_VPP, "amplitude_m")
            self._output, self._target_m = False, 0.0
        except BaseException:
            self._connected = False
            self.backend.close()
            raise
        atexit.register(self._at_exit)
        return self

    def close(self) -> None:
        """Output off (at once, no ramp), then release the link.

        DeviceError when the link worked but the generator did not confirm the output off
        (the lab must switch it off by hand); after a link failure the off command is sent
        without waiting for an answer and the failure already raised says the rest.
        """
        if not self._connected:
            return
        self._interrupt_ramp()
        problem: DeviceError | None = None
        with self._io_lock:
            try:
                if self._link_failure is None:
                    self._output_off_confirmed()
                else:
                    self._make_safe()
            except DeviceError as error:
                if isinstance(error, ScpiLinkError):
                    self._link_failure = error  # the retry below is sent without waiting
                self._make_safe()
                problem = error
            finally:
                self.backend.close()
                self._connected = False
        atexit.unregister(self._at_exit)
        if problem is not None:
            log.error("%s: could not confirm the output off: %s", self.name, problem)
            raise DeviceError(
                f"{self.name}: could not confirm the output off ({problem}); switch it off "
                "at the generator"
            ) from None

    # ------------------------------------------------------------------ settings

    @property
    def frequency_hz(self) -> float:
        """Drive frequency [Hz], read back from the generator; assigning checks the limits,
        sends it and confirms it (the generator jumps to it, phase-continuously)."""
        return self._io("read frequency_hz", self._query_number, f"SOUR{self.channel}:FREQ?")

    @frequency_hz.setter
    def frequency_hz(self, value: float) -> None:
        checked = _check(self.limits, "frequency_hz", value)
        with self._command_lock:
            self._io(
                "write frequency_hz",
                self._confirm_number,
                "frequency_hz",
                f"SOUR{self.channel}:FREQ",
                round(checked, 6),
                "Hz",
                FREQUENCY_TOLERANCE_HZ,
            )

    @property
    def amplitude_m(self) -> float:
        """Table displacement amplitude [m]: the generator's amplitude read back times the gain.
        Assigning checks the limits and the volts ceiling, then ramps to it at
        ``ramp_rate_m_s`` when the output is on, or sets it at once when it is off."""
        vpp = self._io("read amplitude_m", self._query_number, f"SOUR{self.channel}:VOLT?")
        return self._metres(vpp)

    @amplitude_m.setter
    def amplitude_m(self, value: float) -> None:
        checked = _check(self.limits, "amplitude_m", value)
        vpp = self._vpp_for(checked)
        with self._command_lock:
            generation = self._ramp_generation  # a stop from now on cuts the ramp short
            self._target_m = checked
            if self._output:
                self._ramp_to(vpp, generation)
            else:
                self._io("write amplitude_m", self._send_vpp, vpp, "amplitude_m")

    @property
    def ramp_rate_m_s(self) -> float:
        """How fast the host moves the amplitude [m/s] (held by the host, not the generator)."""
        return self._ramp_rate_m_s

    @ramp_rate_m_s.setter
    def ramp_rate_m_s(self, value: float) -> None:
        self._ramp_rate_m_s = _check(self.limits, "ramp_rate_m_s", value)

    @property
    def enabled(self) -> bool:
        """Output on (True) or off, read back from the generator."""
        return _is_on(self._io("read enable", self.backend.query, f"OUTP{self.channel}?"))

    @enabled.setter
    def enabled(self, on: bool) -> None:
        if not isinstance(on, bool):
            raise TypeError(f"enabled = {on!r}: expected True or False")
        if not on:
            self.stop()
            return
        with self._command_lock:
            generation = self._ramp_generation  # a stop from now on cuts the ramp short
            if not self._output:
                self._io("write amplitude_m", self._send_vpp, MIN_VPP, "amplitude_m")
                self._io("enable", self._set_output, True)
            self._ramp_to(self._vpp_for(self._target_m), generation)

    def stop(self, wait_s: float = 0.0) -> None:
        """Ramp the amplitude down at ``ramp_rate_m_s``, then turn the output off (confirmed).

        A ramp running in another thread is cut short first.  Safe at any time and more
        than once; ``wait_s`` is accepted for the Modbus amplifier's signature (the ramp
        down is done before this returns).
        """
        del wait_s
        self._interrupt_ramp()
        with self._command_lock:
            self._target_m = 0.0
            if self._output:  # a failure in the ramp has turned the output off already
                self._ramp_to(MIN_VPP, self._ramp_generation)
            self._io("disable", self._output_off_confirmed)

    def clear_faults(self) -> None:
        """Clear the generator's error queue (``*CLS``); it latches no drive faults."""
        self._io("clear faults", self._done, "*CLS")

    # ------------------------------------------------------------------ readings

    def measured(self) -> MeasuredDrive:
        """The generator's output read back: frequency, amplitude (0 while off), ramping."""
        s = self.setpoints()
        amplitude = s.amplitude_m if s.enabled else 0.0
        return MeasuredDrive(
            frequency_hz=s.frequency_hz,
            amplitude_m=amplitude,
            enabled=s.enabled,
            ramping=self._ramping,
            at_zero=not s.enabled,
            faults=(),
        )

    def setpoints(self) -> Setpoints:
        """What the generator holds now (whoever set it), and the host's ramp rate."""
        with self._io_lock:
            frequency = self.frequency_hz
            vpp = self._io("read amplitude_m", self._query_number, f"SOUR{self.channel}:VOLT?")
            on = self.enabled
        return Setpoints(frequency, self._metres(vpp), self._ramp_rate_m_s, on)

    def faults(self) -> tuple[str, ...]:
        """Always empty: a generator latches no drive faults (its errors raise where they occur)."""
        return ()

    def _holds(self, m: MeasuredDrive) -> str:
        return f"generator holds {m.amplitude_m:.6g} m at {m.frequency_hz:.6g} Hz"

    # ------------------------------------------------------------------ internals

    def _metres(self, vpp: float) -> float:
        return vpp / 2.0 * self.gain_m_per_v

    def _vpp_for(self, amplitude_m: float) -> float:
        """Vpp for ``amplitude_m`` (0.1 mV resolution); LimitError above ``max_output_vpp``."""
        vpp = round(2.0 * amplitude_m / self.gain_m_per_v, VPP_DECIMALS)
        if vpp > self.max_output_vpp:
            raise LimitError(
                f"shaker amplitude_m = {amplitude_m!r} m needs {vpp:g} Vpp at gain "
                f"{self.gain_m_per_v:g} m/V, above the generator limit max_output_vpp "
                f"{self.max_output_vpp:g} Vpp; nothing was sent to the generator"
            )
        return max(vpp, MIN_VPP)

    def _ramp_to(self, target_vpp: float, generation: int) -> None:
        """Step the amplitude (output on) to ``target_vpp``, each step confirmed.

        A step is at most ``ramp_rate * ramp_step_s`` and steps are at least ``ramp_step_s``
        apart, so the amplitude never moves faster than the ramp rate (a slow link makes the
        ramp slower, never steeper).  RampInterruptedError once a stop or close came after
        ``generation`` was read (the caller reads it when its command sequence begins).
        """
        rate_vpp_s = 2.0 * self._ramp_rate_m_s / self.gain_m_per_v
        # a step smaller than the 0.1 mV the generator holds would never arrive: slower steps
        step_vpp = max(rate_vpp_s * self.ramp_step_s, VPP_RESOLUTION)
        interval_s = step_vpp / rate_vpp_s
        self._wake.clear()
        self._ramping = True
        try:
            while True:
                began = time.monotonic()
                gap = target_vpp - self._vpp
                vpp = (
                    target_vpp if abs(gap) <= step_vpp else self._vpp + math.copysign(step_vpp, gap)
                )
                with self._io_lock:
                    if generation != self._ramp_generation:
                        raise RampInterruptedError(
                            f"{self.name}: amplitude ramp stopped at "
                            f"{self._metres(self._vpp):.6g} m by a stop from another thread"
                        )
                    self._io(
                        "write amplitude_m", self._send_vpp, round(vpp, VPP_DECIMALS), "amplitude_m"
                    )
                if vpp == target_vpp:
                    return
                self._wake.wait(max(0.0, began + interval_s - time.monotonic()))
        finally:
            self._ramping = False

    def _interrupt_ramp(self) -> None:
        self._ramp_generation += 1
        self._wake.set()

    def _send_vpp(self, vpp: float, setting: str) -> None:
        self._confirm_number(
            setting,
            f"SOUR{self.channel}:VOLT",
            vpp,
            "Vpp",
            max(AMPLITUDE_TOLERANCE_VPP, AMPLITUDE_TOLERANCE_FRACTION * vpp),
        )
        self._vpp = vpp

    def _set_output(self, on: bool) -> None:
        self._confirm_word(
            "enable",
            f"OUTP{self.channel} {'ON' if on else 'OFF'}",
            f"OUTP{self.channel}?",
            "1" if on else "0",
        )
        self._output = on

    def _output_off_confirmed(self) -> None:
        """Output off, confirmed by ``OUTP?`` alone: an error queued meanwhile (reported
        where it happened) must not make an output that is off look on."""
        held = self.backend.query(f"OUTP{self.channel} OFF;OUTP{self.channel}?")
        if _is_on(held):
            raise SettingNotConfirmedError(
                f"{self.backend.description}: enable not confirmed: sent 'OUTP{self.channel} "
                f"OFF', 'OUTP{self.channel}?' answered {held!r}"
            )
        self._output = False

    def _confirm_number(
        self, setting: str, header: str, value: float, unit: str, tolerance: float
    ) -> None:
        """Send ``header value``, wait for it, read the error queue and the value back."""
        command = f"{header} {value:.10g}"
        self._settle(setting, command)
        held = self._query_number(f"{header}?")
        if abs(held - value) > tolerance:
            raise SettingNotConfirmedError(
                f"{self.backend.description}: {setting} not confirmed: sent '{command}' "
                f"({unit}), the generator holds {held:.10g} {unit}"
            )

    def _confirm_word(self, setting: str, command: str, query: str, expected: str) -> None:
        self._settle(setting, command)
        held = self.backend.query(query)
        if held.strip().strip('"').upper() != expected:
            raise SettingNotConfirmedError(
                f"{self.backend.description}: {setting} not confirmed: sent '{command}', "
                f"'{query}' answered {held!r}, expected {expected!r}"
            )

    def _done(self, command: str) -> None:
        """Send ``command`` with ``*OPC?`` on the same line and wait for its "1".

        One line per exchange: a command written alone and then a query would wait for
        the instrument's delayed TCP acknowledgement (Nagle), some 40 ms each time.
        """
        done = self.backend.query(f"{command};*OPC?")
        if done.strip() not in ("1", "+1"):
            raise ScpiLinkError(
                f"{self.backend.description}: '*OPC?' answered {done!r} after '{command}'"
            )

    def _settle(self, setting: str, command: str) -> None:
        """Send ``command``, wait until done (``*OPC?``), then empty the error queue."""
        self._done(command)
        errors = []
        for _ in range(MAX_ERRORS_READ):
            entry = self.backend.query("SYST:ERR?")
            if entry.lstrip("+").startswith("0,") or entry.lstrip("+").startswith("0 "):
                break
            errors.append(entry)
        if errors:
            raise InstrumentError(
                f"{self.backend.description}: {setting}: the generator reported "
                f"{'; '.join(errors)} after '{command}'"
            )

    def _query_number(self, query: str) -> float:
        answer = self.backend.query(query)
        try:
            return float(answer)
        except ValueError:
            raise ScpiLinkError(
                f"{self.backend.description}: '{query}' answered {answer!r}, not a number"
            ) from None

    def _failed(self, what: str, error: DeviceError) -> DeviceError:
        """Turn the output off (blind after a link failure); the error, in one line."""
        link_failed = isinstance(error, ScpiLinkError | DeviceNotFoundError)
        if link_failed:
            self._link_failure = error
        self._make_safe()
        off = (
            "the output was commanded off (not confirmed: the link failed)"
            if link_failed
            else "the output was turned off"
        )
        return type(error)(f"{error}; '{what}' failed, {off}")

    def _make_safe(self) -> None:
        """Best effort: output off.  Confirmed while the link works; sent blind after a failure."""
        with self._io_lock:
            try:
                if self._link_failure is None:
                    self._output_off_confirmed()
                else:
                    self.backend.write(f"OUTP{self.channel} OFF")
                    self._output = False
            except DeviceError as error:
                log.error("%s: could not turn the output off: %s", self.name, error)

    def _at_exit(self) -> None:
        try:
            self.close()
        except DeviceError as error:
            log.error("%s: at exit: %s", self.name, error)


def _check(limits: ShakerLimits, name: str, value: float) -> float:
    ShakerAmplifier.check_settings(limits, **{name: value})
    return float(value)


def _is_on(answer: str) -> bool:
    return answer.strip().upper() in ("1", "+1", "ON")


def _identity(link: ScpiLink, answer: str) -> GeneratorIdentity:
    fields = [part.strip() for part in answer.split(",")]
    if len(fields) != 4 or not fields[1]:
        raise WrongDeviceError(
            f"{link.description} answered '*IDN?' with {answer!r}; expected "
            "'maker,model,serial,firmware' from a function generator (check the address and port)"
        )
    return GeneratorIdentity(*fields)


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__
