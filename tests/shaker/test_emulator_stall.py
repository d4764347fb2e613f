"""The emulator's own stall is not the host's silence: its watchdog clock (``AwakeClock``)
stands still while its loop cannot run, and a host that keeps heartbeating is not tripped.

The story: the guide's ``sweep --sim`` failed under a loaded test run with "faults latched
(watchdog expired)" while its host heartbeated every 0.2 s; the emulator shares the host's
process and cores, and the first request after its loop stood still checked the watchdog
before the heartbeats waiting in the socket were read."""

from __future__ import annotations

import time

from pyModbusTCP.client import ModbusClient

from hardware_sim.amplifier_emulator import AwakeClock

# docs/amplifier_registers.md
HR_AMPLITUDE_UM, HR_ENABLE, HR_HEARTBEAT, HR_WATCHDOG_MS = 2, 4, 5, 7
IR_FAULTS = 4
FAULT_WATCHDOG = 8


class _Wall:
    """A wall clock the test moves by hand."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_the_awake_clock_follows_the_wall_while_the_loop_runs_and_stands_still_in_a_stall():
    wall = _Wall()
    clock = AwakeClock(wall, stall_s=0.1)
    start = clock()
    for _ in range(50):  # a healthy loop: a turn every 20 ms
        wall.now += 0.02
        clock.tick()
    assert clock() - start == wall.now - 100.0
    before = clock()
    wall.now += 3.0  # the loop stands still for 3 s: requests read the clock meanwhile
    during = clock()
    assert abs(during - before - 0.1) < 1e-9  # only the gap a healthy loop may show
    clock.tick()
    assert clock() == during  # the tick changes nothing seen
    for _ in range(50):  # the loop runs again (the host silent): time counts in full
        wall.now += 0.02
        clock.tick()
    assert abs(clock() - during - 1.0) < 1e-9


def test_a_heartbeating_host_is_not_tripped_when_the_emulators_loop_stalls(emulator):
    client = ModbusClient(host="127.0.0.1", port=emulator.port, unit_id=1, timeout=5.0,
                          auto_open=True)
    try:
        assert client.write_single_register(HR_WATCHDOG_MS, 300)
        assert client.write_multiple_registers(HR_AMPLITUDE_UM, [100, 20_000, 1])
        assert client.write_single_register(HR_HEARTBEAT, 1)
        # the emulator's loop stands still for 1 s (as under a starved process); the host's
        # next heartbeat waits in the socket and is answered after the stall
        emulator._loop.call_soon_threadsafe(time.sleep, 1.0)
        time.sleep(0.05)
        assert client.write_single_register(HR_HEARTBEAT, 2)
        assert client.read_input_registers(IR_FAULTS, 1) == [0]
        assert client.read_holding_registers(HR_ENABLE, 1) == [1]
        # and a host that then goes silent is still tripped after its 300 ms
        time.sleep(0.6)
        assert client.read_input_registers(IR_FAULTS, 1) == [FAULT_WATCHDOG]
    finally:
        client.close()
