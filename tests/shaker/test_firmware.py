"""Watchdog timing of the amplifier firmware on a controlled clock (docs/amplifier_registers.md)."""

from __future__ import annotations

from drivers.amplifier_registers import Fault, Holding
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.shaker_response import ShakerResponse


class Clock:
    """A clock the test moves by hand."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _firmware(clock: Clock, response: ShakerResponse | None = None) -> AmplifierFirmware:
    return AmplifierFirmware(response, plant_clock=clock, wall_clock=clock)


def test_watchdog_expires_exactly_after_its_timeout() -> None:
    clock = Clock()
    firmware = _firmware(clock)
    firmware.write(Holding.WATCHDOG_MS, [500])
    firmware.write(Holding.AMPLITUDE_UM, [1000, 5000, 1])  # amplitude, ramp rate, enable
    clock.now += 0.499
    firmware.service()
    assert firmware.enabled and firmware.faults == Fault(0)
    firmware.write(Holding.HEARTBEAT, [1])  # re-armed here
    clock.now += 0.499
    firmware.service()
    assert firmware.enabled
    clock.now += 0.002
    firmware.service()
    assert not firmware.enabled and firmware.faults == Fault.WATCHDOG_EXPIRED
    assert firmware.response.targets[0] == 0.0  # ramping to zero


def test_disabled_drive_needs_no_heartbeat() -> None:
    clock = Clock()
    firmware = _firmware(clock)
    firmware.write(Holding.AMPLITUDE_UM, [1000])
    clock.now += 100.0
    firmware.service()
    assert firmware.faults == Fault(0)


def test_front_panel_start_arms_the_watchdog_at_the_first_heartbeat() -> None:
    clock = Clock()
    response = ShakerResponse(t0_s=clock.now)
    response.settle_at(amplitude_m=0.002, frequency_hz=10.0)
    firmware = _firmware(clock, response)
    assert firmware.enabled and firmware.read_holding(0, 3) == [0, 10000, 2000]
    clock.now += 30.0
    firmware.service()
    assert firmware.enabled  # no host has spoken yet
    firmware.write(Holding.HEARTBEAT, [7])
    clock.now += 1.001  # default timeout 1000 ms
    firmware.service()
    assert firmware.faults == Fault.WATCHDOG_EXPIRED
