"""Bad command-line input gets one clear line naming what was wrong, never a traceback."""

from __future__ import annotations

import pytest

from rig.cli import main


@pytest.mark.parametrize("fs", ["-5", "0", "nan", "inf", "fast"])
def test_a_sample_rate_that_is_not_a_positive_number_is_refused_by_name(tmp_path, capsys, fs):
    out = tmp_path / "run.h5"
    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--sim", "--duration", "1", "--fs", fs, "--out", str(out)])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    assert "argument --fs" in error and "Traceback" not in error
    assert not out.exists()


def test_export_into_a_missing_folder_names_the_folder(tmp_path, capsys):
    from tests.rig.test_replay import _make_recording

    recording = _make_recording(tmp_path / "run.h5", total=4_000)
    out = tmp_path / "missing" / "run.csv"
    assert main(["export", str(recording), "--out", str(out), "--gaps", "longest"]) == 2
    error = capsys.readouterr().err
    assert f"folder {out.parent} does not exist" in error


@pytest.mark.parametrize(
    "option", [["--drive-hz", "10"], ["--beta", "0.03"], ["--amplitude-mm", "1"]]
)
def test_a_drive_setting_for_a_decay_is_refused_not_ignored(tmp_path, capsys, option):
    out = tmp_path / "decay.h5"
    args = ["record", "--sim", "--experiment", "free_decay", *option, "--out", str(out)]
    assert main(args) == 2
    error = capsys.readouterr().err
    assert f"{option[0]} makes no sense for a free_decay" in error
    assert "opening the devices" not in error and not out.exists()


@pytest.mark.parametrize("option", ["--settle", "--pretrigger"])
def test_a_negative_time_is_refused_before_the_rig_opens(tmp_path, capsys, option):
    out = tmp_path / "run.h5"
    assert main(["record", "--sim", option, "-1", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert f"{option} is -1.0; expected a number of seconds >= 0" in error
    assert "opening the devices" not in error and not out.exists()
