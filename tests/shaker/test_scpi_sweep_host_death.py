"""`impact-rig sweep` through a SCPI generator, killed mid-sweep: the emulated generator's output
goes off when the dead host's connection closes (a real generator would keep driving:
docs/scpi_generator.md says what the lab must add)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hardware_sim.sim_rig import SimRig
from rig.config import default_config_path
from tests.host_process import end, start_rig_cli

GAIN_M_PER_V = 2.0e-3
BETA = 0.02  # amplitude = BETA * L_m = 0.92 mm: 0.92 Vpp at 2 mm/V


def real_rig_file(daq_port: str, resource: str) -> str:
    """The shipped rig file as a real rig whose devices are the given ports."""
    text = default_config_path().read_text()
    for old, new in (
        ('kind = "virtual"', 'kind = "real"'),
        ('port = "sim"', f'port = "{daq_port}"'),
        (
            'kind = "modbus"\n',
            f'kind = "scpi"\nresource = "{resource}"\ngain_m_per_v = {GAIN_M_PER_V}\n',
        ),
    ):
        assert old in text
        text = text.replace(old, new, 1)
    return text


@pytest.mark.slow
def test_a_sweep_host_killed_mid_sweep_leaves_the_emulated_generator_off(tmp_path: Path) -> None:
    with SimRig(drive="scpi", gain_m_per_v=GAIN_M_PER_V) as sim:
        ends = sim.endpoints
        assert ends.daq_port is not None and ends.scpi is not None
        config = tmp_path / "scpi_rig.toml"
        config.write_text(real_rig_file(ends.daq_port, ends.scpi))
        host = start_rig_cli(
            "sweep", "--config", str(config), "--sweep", "frequency", "--start", "4",
            "--stop", "8", "--steps", "3", "--beta", str(BETA), "--settle", "30",
            "--dwell", "1", "--quiet", "--out", str(tmp_path / "sweep.h5"),
        )  # fmt: skip
        try:
            driving = sim.generator.wait_for(
                lambda state: state.output and state.amplitude_vpp > 0.9, 120.0
            )
            assert driving, host.poll() is not None and host.communicate()[1]
            assert sim.generator.state.frequency_hz == 4.0
            host.kill()  # SIGKILL mid-step: no atexit, no close
            host.wait(10)
            assert sim.generator.wait_for(lambda state: not state.output, 5.0)
            assert sim.generator.watchdog_trips == 1
        finally:
            end(host)
