"""Protocol conformance from outside: the independent pyModbusTCP client, the documented map only.

Addresses and scalings below are typed from docs/amplifier_registers.md, not
imported from our code, so a change of the map that forgets the document fails here.
"""

from __future__ import annotations

import time

from pyModbusTCP.client import ModbusClient

from hardware_sim.amplifier_emulator import AmplifierEmulator

# docs/amplifier_registers.md
HR_FREQUENCY_MHZ, HR_AMPLITUDE_UM, HR_RAMP_RATE, HR_ENABLE, HR_HEARTBEAT = 0, 2, 3, 4, 5
HR_COMMAND, HR_WATCHDOG_MS = 6, 7
IR_MODEL, IR_STATUS, IR_FAULTS, IR_MEASURED_F, IR_MEASURED_A = 0, 3, 4, 5, 7
STATUS_ENABLED, STATUS_RAMPING, STATUS_AT_ZERO, STATUS_FAULTED = 1, 2, 4, 8
FAULT_WATCHDOG = 8


def _client(emulator: AmplifierEmulator) -> ModbusClient:
    client = ModbusClient(
        host="127.0.0.1", port=emulator.port, unit_id=1, timeout=1.0, auto_open=True
    )
    assert client.open(), client.last_error_as_txt
    return client


def _measured(client: ModbusClient) -> tuple[int, int, float, float]:
    regs = client.read_input_registers(IR_STATUS, 5)
    assert regs is not None, client.last_except_as_txt
    status, faults, f_hi, f_lo, amplitude_um = regs
    return status, faults, ((f_hi << 16) | f_lo) / 1000.0, amplitude_um * 1e-6


def test_drive_through_the_documented_map_then_watchdog_trips(emulator: AmplifierEmulator) -> None:
    client = _client(emulator)
    try:
        assert client.read_input_registers(IR_MODEL, 3) == [0x5348, 0x0100, 1]
        assert client.write_single_register(HR_WATCHDOG_MS, 1000)
        frequency_mhz = 12_500
        assert client.write_multiple_registers(
            HR_FREQUENCY_MHZ, [frequency_mhz >> 16, frequency_mhz & 0xFFFF]
        )
        assert client.write_multiple_registers(HR_AMPLITUDE_UM, [1500, 20_000, 1])
        # keep the watchdog fed while the output ramps and settles
        beat, deadline = 0, time.monotonic() + 5.0
        while time.monotonic() < deadline:
            beat += 1
            assert client.write_single_register(HR_HEARTBEAT, beat)
            status, faults, frequency_hz, amplitude_m = _measured(client)
            if not status & STATUS_RAMPING:
                break
            time.sleep(0.05)
        assert status & STATUS_ENABLED and not status & STATUS_FAULTED and faults == 0
        assert abs(frequency_hz - 12.5) < 1e-3
        assert abs(amplitude_m - 1.5e-3) < 1e-6
        assert client.read_input_registers(8, 1) == [beat]  # heartbeat echo
        # the host goes quiet: after 1000 ms the amplifier ramps to zero and latches the fault
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            status, faults, _, amplitude_m = _measured(client)
            if status & STATUS_AT_ZERO:
                break
            time.sleep(0.05)
        assert faults == FAULT_WATCHDOG
        assert status & STATUS_FAULTED and not status & STATUS_ENABLED
        assert amplitude_m == 0.0
        assert client.read_holding_registers(HR_ENABLE, 1) == [0]
        # enabling again is refused until the fault is cleared
        assert not client.write_single_register(HR_ENABLE, 1)
        assert client.last_except == 3
        assert client.write_single_register(HR_COMMAND, 1)
        assert _measured(client)[1] == 0
    finally:
        client.close()
