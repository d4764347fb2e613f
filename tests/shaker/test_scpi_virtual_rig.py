"""The virtual rig with a SCPI generator as the shaker's drive: the generator's volts, through
the emulated amplifier's gain, move the simulated table; the rig file and `sim-rig` choose it."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable

from drivers.limits import ShakerLimits
from drivers.scpi_shaker import ScpiLink, ScpiShaker
from hardware_sim.sim_rig import SimRig
from rig.config import default_config_path, parse_config
from rig.devices import open_rig
from tests.host_process import end, read_endpoints, start_rig_cli

GAIN_M_PER_V = 2.0e-3


def eventually(condition: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    """Poll ``condition`` until it holds (True) or ``timeout_s`` passed (False)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def test_the_generators_volts_move_the_simulated_table_through_the_gain() -> None:
    with SimRig(daq=False, drive="scpi", gain_m_per_v=GAIN_M_PER_V) as sim:
        assert sim.endpoints.modbus_tcp is None and sim.endpoints.scpi is not None
        link = ScpiLink(sim.endpoints.scpi, timeout_s=0.5)
        with ScpiShaker(link, ShakerLimits(), gain_m_per_v=GAIN_M_PER_V) as shaker:
            shaker.ramp_rate_m_s = 0.02
            shaker.frequency_hz = 5.0
            shaker.amplitude_m = 0.001  # 1 Vpp at 2 mm/V
            shaker.enabled = True
            assert sim.generator.state.amplitude_vpp == 1.0
            assert eventually(lambda: abs(sim.rig.table_output.amplitude_m - 0.001) < 1e-6)
            assert eventually(lambda: abs(sim.rig.table_output.frequency_hz - 5.0) < 1e-3)
        assert eventually(lambda: sim.rig.table_output.at_zero)  # output off: the table stops


def test_a_virtual_scpi_rig_file_opens_the_rig_with_the_generator_drive() -> None:
    text = (
        default_config_path()
        .read_text()
        .replace(
            'kind = "modbus"\n', f'kind = "scpi"\nresource = "sim"\ngain_m_per_v = {GAIN_M_PER_V}\n'
        )
    )
    config = parse_config(text, "scpi_rig.toml")
    with open_rig(config) as devices:
        assert isinstance(devices.shaker, ScpiShaker)
        assert devices.sim.generator.resource == devices.shaker.backend.resource
        shaker = devices.identities()["shaker"]
        assert (shaker["kind"], shaker["model"]) == ("scpi", "Emulated SCPI generator")
        devices.shaker.frequency_hz = 6.0
        devices.shaker.amplitude_m = 0.0005
        devices.shaker.enabled = True
        assert devices.sim.generator.state.output
        generator = devices.sim.generator
    assert not generator.state.output  # closing the rig turned it off first


def test_sim_rig_command_serves_the_scpi_generator() -> None:
    process = start_rig_cli(
        "sim-rig", "--drive", "scpi", "--scpi-port", "0", "--gain", "2e-3", "--no-daq", stdin=True
    )
    try:
        assert process.stdout is not None and process.stdin is not None
        endpoints = read_endpoints(process)
        assert "modbus-tcp" not in endpoints
        resource = endpoints["scpi-generator"].split()[0]  # then "(gain 0.002 m/V)"
        link = ScpiLink(resource, timeout_s=1.0)
        with ScpiShaker(link, ShakerLimits(), gain_m_per_v=GAIN_M_PER_V) as shaker:
            shaker.ramp_rate_m_s = 0.02
            shaker.frequency_hz = 4.0
            shaker.amplitude_m = 0.002
            shaker.enabled = True
            process.stdin.write("status\n")
            process.stdin.flush()
            status = process.stdout.readline()
            assert "amplitude_vpp=2.0" in status and "output=True" in status
            process.stdin.write("trip over_current\n")
            process.stdin.flush()
            assert "Modbus drive's" in process.stdout.readline()
        process.send_signal(signal.SIGINT)  # Ctrl-C
        out, _ = process.communicate(timeout=20)
        assert "stopped" in out
    finally:
        end(process)
