"""The rig file's [virtual.causes] table: validated against the cause registry, and the
virtual rig started from the file really carries the effect."""

from __future__ import annotations

import pytest

from rig.cli import build_parser
from rig.commands.demo import hidden_from_options
from rig.config import ConfigError, load_config, parse_config
from rig.demo.record import demo_config
from rig.devices import open_rig

BASE = load_config().text


def _with_causes(lines: str):
    return parse_config(BASE + "\n[virtual.causes]\n" + lines + "\n", "lab.toml")


def test_the_shipped_rig_has_no_hidden_cause():
    assert dict(load_config().virtual.causes) == {}


def test_causes_are_read_with_defaults_for_the_parameters_left_out():
    config = _with_causes("coulomb_friction = { Tc_N_m = 2e-5 }\nsensor_offset = {}")
    causes = {name: dict(values) for name, values in config.virtual.causes.items()}
    assert causes == {"coulomb_friction": {"Tc_N_m": 2e-5}, "sensor_offset": {"offset_rad": 0.0}}


@pytest.mark.parametrize(
    ("line", "key", "expected"),
    [
        ("coulomb_friction = { Tc_N_m = 5 }", "virtual.causes.coulomb_friction.Tc_N_m", "[0, 1]"),
        ("coulomb_friction = { Tc_N_m = 'x' }", "coulomb_friction.Tc_N_m", "a number"),
        ("coulomb_friction = { Tc = 1e-5 }", "virtual.causes.coulomb_friction.Tc", "Tc_N_m"),
        ("friction = { Tc_N_m = 1e-5 }", "virtual.causes.friction", "coulomb_friction"),
        ("coulomb_friction = 3", "virtual.causes.coulomb_friction", "must be a table"),
    ],
)
def test_a_bad_cause_names_the_file_the_key_and_what_was_expected(line, key, expected):
    with pytest.raises(ConfigError) as caught:
        _with_causes(line)
    message = str(caught.value)
    assert message.startswith("lab.toml: ")
    assert key in message and expected in message


def test_the_virtual_rig_runs_the_model_with_the_files_causes():
    config = _with_causes("coulomb_friction = { Tc_N_m = 3e-5 }")
    with open_rig(config) as devices:
        model = devices.sim.rig.model
        assert {k: dict(v) for k, v in model.extensions.items()} == {
            "coulomb_friction": {"Tc_N_m": 3e-5}
        }


@pytest.mark.parametrize(
    ("options", "file_causes", "expected"),
    [
        (["--cause", "sensor_offset", "--param", "offset_rad=0.004"], "",
         {"sensor_offset": {"offset_rad": 0.004}}),
        ([], "", {"coulomb_friction": {"Tc_N_m": 2e-5}}),  # the demo's default
        ([], "barrier_offset = { theta_b_rad = 0.01 }",
         {"barrier_offset": {"theta_b_rad": 0.01}}),
        (["--cause", "none"], "coulomb_friction = { Tc_N_m = 3e-5 }", {}),
    ],
    ids=["--cause", "default", "the rig file's", "--cause none over the rig file's"],
)
def test_the_demos_cause_is_the_one_its_virtual_rig_runs(tmp_path, options, file_causes,
                                                         expected):
    rig_file = tmp_path / "lab.toml"
    rig_file.write_text(BASE + (f"\n[virtual.causes]\n{file_causes}\n" if file_causes else ""),
                        encoding="utf-8")
    args = build_parser().parse_args(["demo", "--config", str(rig_file), *options])
    hidden = hidden_from_options(args)
    with open_rig(demo_config(load_config(rig_file), hidden)) as devices:
        model = devices.sim.rig.model
        assert {k: dict(v) for k, v in model.extensions.items()} == expected
