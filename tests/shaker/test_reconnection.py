"""The amplifier's Modbus link lost and found again: the driver reconnects on its own, and
the drive is off until someone asks for it again (never on while unconfirmed).

A real pymodbus server (the amplifier emulator) on loopback TCP, the real TCP backend.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest

from drivers.amplifier_registers import Fault, Holding
from drivers.interfaces import DeviceError
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator, TransportFault
from tests.shaker.conftest import LIMITS, make_firmware


def wait_for(what: str, condition: Callable[[], object], within_s: float = 10.0) -> None:
    deadline = time.monotonic() + within_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {within_s} s")
        time.sleep(0.02)


def driving(emulator: AmplifierEmulator) -> ShakerAmplifier:
    backend = ModbusTcpBackend("127.0.0.1", emulator.port, timeout_s=0.3, retries=0)
    shaker = ShakerAmplifier(backend, LIMITS, watchdog_s=0.5, reconnect=True).connect()
    shaker.ramp_rate_m_s = 0.05
    shaker.frequency_hz = 10.0
    shaker.amplitude_m = 0.002
    shaker.enabled = True
    assert shaker.wait_settled(timeout_s=5.0).amplitude_m == pytest.approx(0.002)
    return shaker


def test_a_silent_link_is_reached_again_and_the_drive_is_left_off() -> None:
    emulator = AmplifierEmulator(make_firmware()).start()
    firmware = emulator.firmware
    shaker = driving(emulator)
    try:
        emulator.fault = TransportFault.NO_REPLY  # the cable, or a switch, drops everything
        with pytest.raises(DeviceError, match="no reply"):
            shaker.measured()
        assert shaker.reconnecting and not shaker.connected
        assert "reconnecting" in shaker.status().faults[0]
        with pytest.raises(DeviceError, match="communication failed earlier"):
            shaker.enabled = True  # refused while the link is not confirmed
        # the host is silent meanwhile: the amplifier's watchdog stops the table
        wait_for("the watchdog stopping the drive", lambda: firmware.response.output().at_zero)
        assert firmware.faults & Fault.WATCHDOG_EXPIRED
        emulator.fault = TransportFault.NONE
        wait_for("the driver reaching the amplifier again", lambda: shaker.connected)
        assert shaker.reconnections == 1 and not shaker.reconnecting
        # what the host had asked before the loss is not resumed: drive off, amplitude 0
        assert firmware.read_holding(int(Holding.ENABLE), 1) == [0]
        assert firmware.read_holding(int(Holding.AMPLITUDE_UM), 1) == [0]
        shaker.clear_faults()
        shaker.amplitude_m = 0.001  # and the link works again, heartbeat included
        shaker.enabled = True
        assert shaker.wait_settled(timeout_s=5.0).amplitude_m == pytest.approx(0.001)
        assert not shaker.measured().faults
    finally:
        emulator.fault = TransportFault.NONE
        shaker.close()
        emulator.stop()
    assert not firmware.enabled  # close() stopped the drive


def test_an_amplifier_restart_is_reached_again_on_its_address() -> None:
    first = AmplifierEmulator(make_firmware()).start()
    port = first.port
    shaker = driving(first)
    second = None
    try:
        first.stop()  # the controller restarts: its server goes away ...
        wait_for("the driver noticing", lambda: shaker.reconnecting)
        second = AmplifierEmulator(make_firmware(), port=port).start()  # ... and comes back
        wait_for("the driver reaching it again", lambda: shaker.connected)
        firmware = second.firmware
        assert firmware.read_holding(int(Holding.ENABLE), 1) == [0]
        assert firmware.read_holding(int(Holding.WATCHDOG_MS), 1) == [500]  # armed again
        assert shaker.measured().at_zero
    finally:
        shaker.close()
        first.stop()
        if second is not None:
            second.stop()
