"""The amplifier controller's firmware: docs/amplifier_registers.md acting on a ShakerResponse.

Transport-free, so the Modbus emulator (TCP and RTU) and the tests' in-process
backend run exactly the same register logic: validation, watchdog, latched faults.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from drivers.amplifier_registers import (
    DEVICE_MAX_AMPLITUDE_UM,
    DEVICE_MAX_FREQUENCY_MHZ,
    DEVICE_MAX_RAMP_RATE_UM_S,
    HOLDING_COUNT,
    INPUT_COUNT,
    MAP_VERSION,
    MODEL_CODE,
    WATCHDOG_DEFAULT_MS,
    WATCHDOG_MAX_MS,
    WATCHDOG_MIN_MS,
    Command,
    Fault,
    Holding,
    Input,
    Status,
    join_u32,
    split_u32,
)
from hardware_sim.shaker_response import ShakerResponse

ILLEGAL_ADDRESS = 0x02
ILLEGAL_VALUE = 0x03


class RegisterAccessError(Exception):
    """A request the controller refuses; ``code`` is the Modbus exception code to answer."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass
class _Setpoints:
    frequency_mhz: int = 0
    amplitude_um: int = 0
    ramp_rate_um_s: int = 0
    enable: int = 0
    heartbeat: int = 0
    watchdog_ms: int = WATCHDOG_DEFAULT_MS


class AmplifierFirmware:
    """Register-level behaviour of the shaker amplifier controller (thread-safe).

    ``plant_clock`` advances the shaker response on every access (a stand-alone
    amplifier on the wall clock); pass None when someone else (the virtual rig's
    stream clock) advances it.  ``wall_clock`` times the watchdog.
    """

    def __init__(
        self,
        response: ShakerResponse | None = None,
        *,
        plant_clock: Callable[[], float] | None = time.monotonic,
        wall_clock: Callable[[], float] = time.monotonic,
        model_code: int = MODEL_CODE,
        firmware_version: tuple[int, int] = (1, 0),
    ) -> None:
        self.response = response or ShakerResponse(
            t0_s=plant_clock() if plant_clock is not None else 0.0
        )
        self._plant_clock = plant_clock
        self.wall_clock = wall_clock  # an emulator swaps in its awake clock (AwakeClock)
        self._lock = threading.RLock()
        self.model_code = model_code
        self.firmware_version = firmware_version
        amplitude_m, frequency_hz, ramp_m_s = self.response.targets
        self._set = _Setpoints(
            frequency_mhz=round(frequency_hz * 1000),
            amplitude_um=round(amplitude_m * 1e6),
            ramp_rate_um_s=max(1, round(ramp_m_s * 1e6)),
            enable=1 if amplitude_m > 0 else 0,
        )
        self._faults = Fault(0)
        self._interlock_open = False
        self._last_heartbeat: float | None = None  # None: not armed yet (front-panel start)
        self._apply_targets()

    # ------------------------------------------------------------------ register access

    def read_input(self, address: int, count: int) -> list[int]:
        """Input registers ``address .. address+count-1`` (FC4)."""
        with self._lock:
            self.service()
            _check_range(address, count, INPUT_COUNT, "input")
            out = self.response.output()
            amplitude_um = min(round(out.amplitude_m * 1e6), 0xFFFF)
            status = Status(0)
            if self._set.enable:
                status |= Status.ENABLED
            if out.ramping:
                status |= Status.RAMPING
            if amplitude_um == 0:  # the bit never contradicts the register beside it
                status |= Status.AT_ZERO
            if self._faults:
                status |= Status.FAULTED
            regs = [0] * INPUT_COUNT
            regs[Input.MODEL_CODE] = self.model_code
            regs[Input.FIRMWARE] = (self.firmware_version[0] << 8) | self.firmware_version[1]
            regs[Input.MAP_VERSION] = MAP_VERSION
            regs[Input.STATUS] = int(status)
            regs[Input.FAULTS] = int(self._faults)
            hi, lo = split_u32(min(round(out.frequency_hz * 1000), 0xFFFF_FFFF))
            regs[Input.MEASURED_FREQUENCY_MHZ_HI] = hi
            regs[Input.MEASURED_FREQUENCY_MHZ_LO] = lo
            regs[Input.MEASURED_AMPLITUDE_UM] = amplitude_um
            regs[Input.HEARTBEAT_ECHO] = self._set.heartbeat
            return regs[address : address + count]

    def read_holding(self, address: int, count: int) -> list[int]:
        """Holding registers ``address .. address+count-1`` (FC3)."""
        with self._lock:
            self.service()
            _check_range(address, count, HOLDING_COUNT, "holding")
            s = self._set
            regs = [0] * HOLDING_COUNT
            regs[Holding.FREQUENCY_MHZ_HI], regs[Holding.FREQUENCY_MHZ_LO] = split_u32(
                s.frequency_mhz
            )
            regs[Holding.AMPLITUDE_UM] = s.amplitude_um
            regs[Holding.RAMP_RATE_UM_S] = s.ramp_rate_um_s
            regs[Holding.ENABLE] = s.enable
            regs[Holding.HEARTBEAT] = s.heartbeat
            regs[Holding.COMMAND] = Command.NONE
            regs[Holding.WATCHDOG_MS] = s.watchdog_ms
            return regs[address : address + count]

    def write(self, address: int, values: Sequence[int]) -> None:
        """Write holding registers (FC6/FC16): all validated first, then applied together."""
        with self._lock:
            self.service()
            _check_range(address, len(values), HOLDING_COUNT, "holding")
            new = dict(zip(range(address, address + len(values)), values, strict=True))
            hi_given = Holding.FREQUENCY_MHZ_HI in new
            if hi_given != (Holding.FREQUENCY_MHZ_LO in new):
                raise RegisterAccessError(
                    ILLEGAL_VALUE, "write both words of FREQUENCY_MHZ (0-1) in one FC16 request"
                )
            s = _Setpoints(**vars(self._set))
            if hi_given:
                s.frequency_mhz = join_u32(
                    new[Holding.FREQUENCY_MHZ_HI], new[Holding.FREQUENCY_MHZ_LO]
                )
                _check_value("FREQUENCY_MHZ", s.frequency_mhz, 0, DEVICE_MAX_FREQUENCY_MHZ)
            if Holding.AMPLITUDE_UM in new:
                s.amplitude_um = _check_value(
                    "AMPLITUDE_UM", new[Holding.AMPLITUDE_UM], 0, DEVICE_MAX_AMPLITUDE_UM
                )
            if Holding.RAMP_RATE_UM_S in new:
                s.ramp_rate_um_s = _check_value(
                    "RAMP_RATE_UM_S", new[Holding.RAMP_RATE_UM_S], 1, DEVICE_MAX_RAMP_RATE_UM_S
                )
            if Holding.WATCHDOG_MS in new:
                s.watchdog_ms = _check_value(
                    "WATCHDOG_MS", new[Holding.WATCHDOG_MS], WATCHDOG_MIN_MS, WATCHDOG_MAX_MS
                )
            command = Command.NONE
            if Holding.COMMAND in new:
                command = Command(_check_value("COMMAND", new[Holding.COMMAND], 0, 1))
            if command == Command.CLEAR_FAULTS:
                self._clear_faults()
            if Holding.ENABLE in new:
                s.enable = _check_value("ENABLE", new[Holding.ENABLE], 0, 1)
                if s.enable and self._faults:
                    raise RegisterAccessError(
                        ILLEGAL_VALUE, f"ENABLE refused: faults latched ({self._faults!r})"
                    )
            now = self.wall_clock()
            if s.enable and not self._set.enable:
                self._last_heartbeat = now  # the watchdog starts when the drive goes on
            if Holding.HEARTBEAT in new:
                s.heartbeat = new[Holding.HEARTBEAT] & 0xFFFF
                self._last_heartbeat = now
            self._set = s
            self._apply_targets()

    # ------------------------------------------------------------------ behaviour

    def service(self) -> None:
        """Advance the plant (stand-alone mode) and check the watchdog; call often."""
        with self._lock:
            if self._plant_clock is not None:
                self.response.advance_to(self._plant_clock())
            if self._set.enable and self._last_heartbeat is not None:
                silent_s = self.wall_clock() - self._last_heartbeat
                if silent_s > self._set.watchdog_ms / 1000.0:
                    self.trip(Fault.WATCHDOG_EXPIRED)

    def trip(self, fault: Fault) -> None:
        """Latch a fault: the drive is disabled and ramps to zero."""
        with self._lock:
            self._faults |= fault
            self._set.enable = 0
            self._apply_targets()

    def set_interlock(self, open_: bool) -> None:
        """Open (True) or close the safety interlock; opening trips INTERLOCK_OPEN."""
        with self._lock:
            self._interlock_open = bool(open_)
            if open_:
                self.trip(Fault.INTERLOCK_OPEN)

    @property
    def faults(self) -> Fault:
        """Latched fault bits."""
        with self._lock:
            return self._faults

    @property
    def enabled(self) -> bool:
        """ENABLE register."""
        with self._lock:
            return bool(self._set.enable)

    def _clear_faults(self) -> None:
        self._faults = Fault.INTERLOCK_OPEN if self._interlock_open else Fault(0)

    def _apply_targets(self) -> None:
        s = self._set
        on = s.enable and not self._faults
        self.response.set_targets(
            amplitude_m=s.amplitude_um * 1e-6 if on else 0.0,
            frequency_hz=s.frequency_mhz / 1000.0,
            ramp_rate_m_s=s.ramp_rate_um_s * 1e-6,
        )


def _check_range(address: int, count: int, size: int, kind: str) -> None:
    if count < 1 or address < 0 or address + count > size:
        raise RegisterAccessError(
            ILLEGAL_ADDRESS,
            f"{kind} registers {address}..{address + count - 1} outside 0..{size - 1}",
        )


def _check_value(name: str, value: int, low: int, high: int) -> int:
    if not low <= value <= high:
        raise RegisterAccessError(ILLEGAL_VALUE, f"{name} = {value} outside {low}..{high}")
    return value
