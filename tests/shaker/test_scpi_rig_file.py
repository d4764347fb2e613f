"""The rig file chooses the shaker's drive, ``shaker.kind = "modbus" | "scpi"``, checked per key."""

from __future__ import annotations

import pytest

from drivers.interfaces import LimitError
from drivers.scpi_shaker import ScpiShaker
from drivers.shaker import ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator
from hardware_sim.scpi_generator import ScpiGeneratorEmulator
from rig.config import ConfigError, default_config_path, parse_config
from rig.devices import open_shaker

DEFAULT = default_config_path().read_text()


def rig_file(shaker_lines: str, *, rig_kind: str = "real") -> str:
    """The shipped file on a real rig, with ``shaker_lines`` in place of ``kind = "modbus"``."""
    text = DEFAULT.replace('kind = "virtual"', f'kind = "{rig_kind}"', 1)
    assert 'kind = "modbus"\n' in text
    return text.replace('kind = "modbus"\n', shaker_lines + "\n", 1)


def scpi_file(resource: str, gain: str = "2.0e-3", extra: str = "") -> str:
    return rig_file(f'kind = "scpi"\nresource = "{resource}"\ngain_m_per_v = {gain}\n{extra}')


def test_the_default_stays_modbus_and_builds_the_amplifier() -> None:
    assert parse_config(DEFAULT).shaker.kind == "modbus"
    with AmplifierEmulator() as emulator:
        text = rig_file('kind = "modbus"').replace("port = 0", f"port = {emulator.port}", 1)
        shaker = open_shaker(parse_config(text, "modbus_rig.toml"))
        try:
            assert isinstance(shaker, ShakerAmplifier)
        finally:
            shaker.close()


def test_a_scpi_rig_file_builds_the_generator_drive_with_its_gain_and_limits() -> None:
    with ScpiGeneratorEmulator() as generator:
        config = parse_config(scpi_file(generator.resource, extra="timeout_s = 0.5"), "scpi.toml")
        assert (config.shaker.kind, config.shaker.gain_m_per_v) == ("scpi", 2.0e-3)
        shaker = open_shaker(config)
        try:
            assert isinstance(shaker, ScpiShaker)
            shaker.amplitude_m = 0.002  # 2 mm at 2 mm/V: 1 V peak, 2 Vpp
            assert generator.state.amplitude_vpp == 2.0
            generator.clear_log()
            with pytest.raises(LimitError, match="amplitude_m"):
                shaker.amplitude_m = 0.0101  # the file's limits.max_amplitude_m is 0.010
            assert generator.received == []
        finally:
            shaker.close()
        assert not generator.state.output


@pytest.mark.parametrize(
    ("text", "key", "expected"),
    [
        (rig_file('kind = "visa"'), "shaker.kind", "one of 'modbus', 'scpi'"),
        (
            rig_file('kind = "scpi"\nresource = "TCPIP::10.0.0.2::5025::SOCKET"'),
            "shaker.gain_m_per_v",
            "missing key",
        ),
        (scpi_file("TCPIP::10.0.0.2::5025::SOCKET", gain="-1e-3"), "shaker.gain_m_per_v", "[1e-07"),
        (scpi_file("10.0.0.2:5025"), "shaker.resource", "a VISA resource"),
        (scpi_file("sim"), "shaker.resource", "a VISA resource"),  # "sim" only on a virtual rig
        (scpi_file("TCPIP::h::5025::SOCKET", extra="timeout_s = 0"), "shaker.timeout_s", "[0.05"),
        (scpi_file("TCPIP::h::5025::SOCKET", extra="channel = 3"), "shaker.channel", "[1, 2]"),
        (
            scpi_file("TCPIP::h::5025::SOCKET", extra="gain_m_per_volt = 1"),
            "shaker.gain_m_per_volt",
            "unknown key",
        ),
        (
            scpi_file("TCPIP::h::5025::SOCKET", gain="1.0e-3", extra="max_output_vpp = 5.0"),
            "limits.max_amplitude_m",  # 10 mm needs 20 Vpp at 1 mm/V
            "at most 0.0025 m",
        ),
    ],
)  # fmt: skip
def test_a_bad_shaker_section_is_one_line_naming_file_and_key(
    text: str, key: str, expected: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        parse_config(text, "scpi_rig.toml")
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith("scpi_rig.toml: ")
    assert f"'{key}'" in message and expected in message


def test_a_virtual_rig_may_name_the_simulated_generator() -> None:
    text = scpi_file("sim").replace('kind = "real"', 'kind = "virtual"', 1)
    assert parse_config(text).shaker.resource == "sim"
