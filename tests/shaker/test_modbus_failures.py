"""Modbus transport failures: missing endpoints, timeouts, exception replies, RTU on a pty."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable

import pytest

from drivers.amplifier_registers import Fault
from drivers.interfaces import DeviceError, DeviceNotFoundError
from drivers.modbus_shaker import ModbusRtuBackend, ModbusTcpBackend
from drivers.shaker import CommandRefusedError, ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator, TransportFault
from tests.shaker.conftest import LIMITS, make_firmware


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(condition: Callable[[], object], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def _tcp(emulator: AmplifierEmulator) -> ModbusTcpBackend:
    return ModbusTcpBackend("127.0.0.1", emulator.port, timeout_s=0.3, retries=0)


def test_nothing_listening_on_the_port_is_a_clear_error() -> None:
    port = _closed_port()
    with pytest.raises(DeviceNotFoundError, match=f"127.0.0.1:{port}"):
        ShakerAmplifier(ModbusTcpBackend("127.0.0.1", port, timeout_s=0.3), LIMITS).connect()


def test_unknown_host_is_a_clear_error() -> None:
    backend = ModbusTcpBackend("no-such-amplifier.invalid", 502, timeout_s=0.3)
    with pytest.raises(DeviceNotFoundError, match=r"no-such-amplifier\.invalid"):
        ShakerAmplifier(backend, LIMITS).connect()


def test_missing_serial_port_is_a_clear_error() -> None:
    with pytest.raises(DeviceNotFoundError, match="/dev/no-such-tty"):
        ShakerAmplifier(ModbusRtuBackend("/dev/no-such-tty"), LIMITS).connect()


@pytest.mark.parametrize("transport", ["tcp", "rtu"])
def test_timeout_fails_cleanly_and_the_amplifier_ends_at_zero(transport: str) -> None:
    emulator = AmplifierEmulator(make_firmware(), tcp=transport == "tcp", rtu=transport == "rtu")
    emulator.start()
    if transport == "tcp":
        backend: ModbusTcpBackend | ModbusRtuBackend = _tcp(emulator)
    else:
        assert emulator.rtu_path is not None
        backend = ModbusRtuBackend(emulator.rtu_path, timeout_s=0.3, retries=0)
    shaker = ShakerAmplifier(backend, LIMITS, watchdog_s=1.0).connect()
    firmware = emulator.firmware
    try:
        shaker.ramp_rate_m_s = 0.05
        shaker.frequency_hz = 10.0
        shaker.amplitude_m = 0.002
        shaker.enabled = True
        assert shaker.wait_settled(timeout_s=5.0).amplitude_m == pytest.approx(0.002)
        assert firmware.faults == Fault(0)  # driving, and the heartbeat got through
        emulator.fault = TransportFault.NO_REPLY
        with pytest.raises(DeviceError, match="no reply"):
            shaker.measured()
        with pytest.raises(DeviceError, match="communication failed earlier"):
            shaker.amplitude_m = 0.001
        assert not shaker.status().connected
        # requests are swallowed, so the driver's own stop cannot arrive either: the host
        # stopped its heartbeat and the amplifier's watchdog stops the table
        assert _wait_for(lambda: firmware.response.output().at_zero, 5.0)
        assert firmware.faults & Fault.WATCHDOG_EXPIRED
    finally:
        emulator.fault = TransportFault.NONE
        shaker.close()
        emulator.stop()


@pytest.mark.parametrize(
    ("fault", "code", "words"),
    [
        (TransportFault.DEVICE_FAILURE, 0x04, "slave device failure"),
        (TransportFault.BUSY, 0x06, "busy"),
    ],
)
def test_exception_reply_fails_cleanly_and_the_amplifier_ends_at_zero(
    emulator: AmplifierEmulator, fault: TransportFault, code: int, words: str
) -> None:
    shaker = ShakerAmplifier(_tcp(emulator), LIMITS, watchdog_s=1.0).connect()
    firmware = emulator.firmware
    try:
        shaker.ramp_rate_m_s = 0.05
        shaker.frequency_hz = 10.0
        shaker.amplitude_m = 0.002
        shaker.enabled = True
        assert shaker.wait_settled(timeout_s=5.0).amplitude_m == pytest.approx(0.002)
        assert firmware.faults == Fault(0)  # driving, and the heartbeat got through
        emulator.fault = fault
        with pytest.raises(CommandRefusedError, match=words) as refused:
            shaker.frequency_hz = 12.0
        assert refused.value.code == code
        emulator.fault = TransportFault.NONE  # the controller recovers; the host does not resume
        assert _wait_for(lambda: firmware.response.output().at_zero, 5.0)
        assert firmware.faults == Fault.WATCHDOG_EXPIRED  # the host's silence stopped it
        assert not firmware.enabled
        assert firmware.read_holding(0, 2) == [0, 10000]  # the refused setpoint never applied
    finally:
        emulator.fault = TransportFault.NONE
        shaker.close()


def test_driver_works_over_modbus_rtu_on_a_pty() -> None:
    with AmplifierEmulator(make_firmware(), tcp=False, rtu=True) as emulator:
        assert emulator.rtu_path is not None
        backend = ModbusRtuBackend(emulator.rtu_path, timeout_s=0.5, retries=0)
        with ShakerAmplifier(backend, LIMITS) as shaker:
            assert shaker.identity is not None and shaker.identity.firmware == "1.0"
            shaker.ramp_rate_m_s = 0.05
            shaker.frequency_hz = 6.5
            shaker.amplitude_m = 0.0015
            shaker.enabled = True
            settled = shaker.wait_settled(timeout_s=5.0)
            assert settled.frequency_hz == pytest.approx(6.5)
            assert settled.amplitude_m == pytest.approx(0.0015)
        assert not emulator.firmware.enabled
        assert any(r.function_code == 16 for r in emulator.requests)


def test_emulator_on_a_port_in_use_fails_clearly_and_leaves_nothing_running() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        threads_before = set(threading.enumerate())
        with pytest.raises(RuntimeError, match=f"could not start on Modbus TCP 127.0.0.1:{port}"):
            AmplifierEmulator(make_firmware(), port=port, rtu=True).start()
    assert _wait_for(lambda: set(threading.enumerate()) <= threads_before, 5.0)
