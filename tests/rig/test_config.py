"""Rig files: the shipped default loads; every bad value is named with file, key and expectation."""

from __future__ import annotations

import pytest

from rig.cli import main
from rig.config import ConfigError, default_config_path, load_config, parse_config

DEFAULT = default_config_path().read_text()


def test_the_shipped_default_is_the_virtual_rig_with_the_paper_constants():
    config = load_config()
    assert config.is_virtual
    assert (config.constants.m_kg, config.constants.l_m, config.constants.L_m) == (
        0.0326,
        0.050,
        0.046,
    )
    assert config.limits.max_amplitude_m <= 0.05
    assert config.text == DEFAULT


@pytest.mark.parametrize(
    ("old", "new", "key", "expected"),
    [
        (
            "max_frequency_hz = 40.0",
            "max_frequency_hz = -4",
            "limits.max_frequency_hz",
            "a number >= 0",
        ),
        ('kind = "virtual"', 'kind = "simulated"', "rig.kind", "one of 'virtual', 'real'"),
        ("m_kg = 0.0326", 'm_kg = "heavy"', "rig.constants.m_kg", "a number > 0"),
        ("angle_input = 0", "angle_input = 7", "daq.angle_input", "an integer in [0, 3]"),
        (
            "m_per_unit = 0.0098304",
            "m_per_unit = 0",
            "calibration.table.m_per_unit",
            "a number whose size is in [1e-12, 1]",
        ),
        (
            "gain_rad_per_v = 0.32768",
            "gain_rad_per_v = 1e308",
            "calibration.angle.gain_rad_per_v",
            "a number whose size is in [1e-06, 100]",
        ),
        ("offset_v = 0.0", "offset_v = -1e300", "calibration.angle.offset_v", "in [-100, 100]"),
        (
            "measuring_range_m = [-0.05, 0.05]",
            "measuring_range_m = [0.05, -0.05]",
            "calibration.table.measuring_range_m",
            "[low, high] with low < high",
        ),
        ("barrier = true", "barrier = 1", "virtual.barrier", "true or false"),
        ("seed = 1", "seed = 1\nsede = 2", "virtual.sede", "expected one of"),
        ("g_m_s2 = 9.81\n", "", "rig.constants.g_m_s2", "missing key"),
    ],
)
def test_a_bad_value_names_file_key_and_what_was_expected(tmp_path, old, new, key, expected):
    assert old in DEFAULT
    bad = tmp_path / "lab.toml"
    bad.write_text(DEFAULT.replace(old, new, 1))
    with pytest.raises(ConfigError) as caught:
        load_config(bad)
    message = str(caught.value)
    assert str(bad) in message and key in message and expected in message


def test_limits_beyond_the_amplifier_are_refused_with_the_file_named(tmp_path):
    bad = tmp_path / "lab.toml"
    bad.write_text(DEFAULT.replace("max_amplitude_m = 0.010", "max_amplitude_m = 0.5"))
    with pytest.raises(ConfigError, match=r"lab\.toml.*max_amplitude_m"):
        load_config(bad)


def test_not_toml_and_missing_file_are_named():
    with pytest.raises(ConfigError, match=r"x\.toml: not valid TOML"):
        parse_config("[rig\nname=", "x.toml")
    with pytest.raises(ConfigError, match=r"nowhere\.toml: rig file not found"):
        load_config("nowhere.toml")


def test_the_command_line_reports_a_bad_rig_file_and_touches_nothing(tmp_path, capsys):
    bad = tmp_path / "lab.toml"
    bad.write_text(DEFAULT.replace("watchdog_s = 1.0", "watchdog_s = 600"))
    out = tmp_path / "run.h5"
    status = main(["record", "--config", str(bad), "--duration", "1", "--out", str(out)])
    assert status == 2
    error = capsys.readouterr().err
    assert str(bad) in error and "limits.watchdog_s" in error and "[0.05, 60]" in error
    assert not out.exists()
