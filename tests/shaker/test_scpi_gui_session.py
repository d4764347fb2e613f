"""The GUI's live session drives a SCPI generator rig unchanged: apply, status, stop, close."""

from __future__ import annotations

import pytest

from drivers.scpi_shaker import ScpiShaker
from gui.worker import LiveSession
from rig.config import default_config_path, parse_config

GAIN_M_PER_V = 2.0e-3


def test_the_gui_session_drives_the_virtual_scpi_rig_as_it_drives_the_modbus_one() -> None:
    text = default_config_path().read_text().replace(
        'kind = "modbus"\n', f'kind = "scpi"\nresource = "sim"\ngain_m_per_v = {GAIN_M_PER_V}\n'
    )
    session = LiveSession.open(parse_config(text, "scpi_rig.toml"))
    try:
        assert isinstance(session.devices.shaker, ScpiShaker)
        generator = session.devices.sim.generator
        session.apply_drive(10.0, 0.001, True, ramp_rate_m_s=0.02)
        assert generator.state.output and generator.state.amplitude_vpp == 1.0
        status = session.shaker_status()
        assert status.connected and status.enabled
        assert status.measured["amplitude_m"] == pytest.approx(0.001)
        session.stop_drive()
        assert not generator.state.output
        assert not session.shaker_status().enabled
    finally:
        session.close()
    assert not generator.state.output
