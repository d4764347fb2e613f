"""The table stops when the host goes away: killed (watchdog) or exiting without close (atexit)."""

from __future__ import annotations

import signal
import subprocess
import time

from drivers.amplifier_registers import Fault
from hardware_sim.amplifier_emulator import AmplifierEmulator
from tests.host_process import end, start_python

HOST = """
import sys, time
from drivers.limits import ShakerLimits
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import ShakerAmplifier
shaker = ShakerAmplifier(ModbusTcpBackend("127.0.0.1", int(sys.argv[1]), timeout_s=0.5),
                         ShakerLimits(max_ramp_rate_m_s=0.05), watchdog_s=1.0).connect()
shaker.ramp_rate_m_s = 0.05
shaker.frequency_hz = 10.0
shaker.amplitude_m = 0.002
shaker.enabled = True
shaker.wait_settled(5.0)
print("driving", flush=True)
if sys.argv[2] == "hang":
    time.sleep(60)
# else: fall off the end without close(): the atexit hook must stop the drive
"""


def _host(port: int, mode: str) -> subprocess.Popen[str]:
    return start_python("-c", HOST, str(port), mode)


def _wait_at_zero(emulator: AmplifierEmulator, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if emulator.firmware.read_input(7, 1) == [0]:  # MEASURED_AMPLITUDE_UM
            return True
        time.sleep(0.02)
    return False


def test_killed_host_leaves_the_table_at_zero_through_the_watchdog(
    emulator: AmplifierEmulator,
) -> None:
    host = _host(emulator.port, "hang")
    try:
        assert host.stdout is not None
        assert host.stdout.readline().strip() == "driving", host.stderr.read()
        assert emulator.firmware.read_input(7, 1) == [2000]
        host.send_signal(signal.SIGKILL)  # no atexit, no close: only the watchdog is left
        host.wait(5)
        assert _wait_at_zero(emulator, 5.0)  # watchdog 1 s, then a 40 ms ramp
        assert emulator.firmware.faults == Fault.WATCHDOG_EXPIRED
        assert not emulator.firmware.enabled
    finally:
        end(host, 5)


def test_host_exiting_without_close_stops_the_drive_itself(emulator: AmplifierEmulator) -> None:
    host = _host(emulator.port, "exit")
    out, err = host.communicate(timeout=20)
    assert host.returncode == 0, err
    assert out.strip() == "driving"
    assert not emulator.firmware.enabled
    assert emulator.firmware.read_holding(2, 1) == [0]  # amplitude setpoint 0
    assert _wait_at_zero(emulator, 3.0)
    assert emulator.firmware.faults == Fault(0)  # the host stopped it, not the watchdog
