"""When the host of a SCPI generator goes away: exiting without close (atexit turns the output off)
and killed (only the emulator's disconnect watchdog can; a real generator keeps driving)."""

from __future__ import annotations

import signal
import subprocess

from hardware_sim.scpi_generator import ScpiGeneratorEmulator
from tests.host_process import end, start_python

HOST = """
import sys, time
from drivers.limits import ShakerLimits
from drivers.scpi_shaker import ScpiLink, ScpiShaker
shaker = ScpiShaker(ScpiLink(sys.argv[1], timeout_s=0.5), ShakerLimits(), gain_m_per_v=1e-3,
                    ramp_step_s=0.01).connect()
shaker.ramp_rate_m_s = 0.02
shaker.frequency_hz = 10.0
shaker.amplitude_m = 0.002
shaker.enabled = True
print("driving", flush=True)
if sys.argv[2] == "hang":
    time.sleep(60)
# else: fall off the end without close(): the atexit hook must turn the output off
"""


def _host(resource: str, mode: str) -> subprocess.Popen[str]:
    return start_python("-c", HOST, resource, mode)


def test_host_exiting_without_close_turns_the_output_off_itself() -> None:
    with ScpiGeneratorEmulator(output_off_on_disconnect=False) as generator:  # as a real one
        host = _host(generator.resource, "exit")
        out, err = host.communicate(timeout=20)
        assert host.returncode == 0, err
        assert out.strip() == "driving"
        assert not generator.state.output
        assert generator.received[-1] == "OUTP1 OFF;OUTP1?"  # the host's atexit said so


def test_killed_host_the_emulators_watchdog_turns_the_output_off() -> None:
    with ScpiGeneratorEmulator() as generator:
        host = _host(generator.resource, "hang")
        try:
            assert host.stdout is not None
            assert host.stdout.readline().strip() == "driving", host.stderr and host.stderr.read()
            assert generator.state.output and generator.state.amplitude_vpp == 4.0
            host.send_signal(signal.SIGKILL)  # no atexit, no close: the kernel closes the socket
            host.wait(5)
            assert generator.wait_for(lambda state: not state.output, 5.0)
            assert generator.watchdog_trips == 1
            assert generator.received[-1] != "OUTP1 OFF;OUTP1?"  # not the host's doing
        finally:
            end(host, 5)


def test_killed_host_a_generator_without_that_watchdog_keeps_driving() -> None:
    """What a real bench generator does; docs/scpi_generator.md says what the lab must add."""
    with ScpiGeneratorEmulator(output_off_on_disconnect=False) as generator:
        host = _host(generator.resource, "hang")
        try:
            assert host.stdout is not None
            assert host.stdout.readline().strip() == "driving"
            host.send_signal(signal.SIGKILL)
            host.wait(5)
            assert generator.wait_for(lambda state: generator.connections == 0, 5.0)
            assert generator.state.output  # still on: nobody turned it off
        finally:
            end(host, 5)
