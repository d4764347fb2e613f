"""``impact-rig suggest`` writes a plan that ``impact-rig sweep --plan`` runs on the virtual
rig, step for step, and ``impact-rig analyze`` takes the first record and the plan's
recording together as one rig; a report with nothing to tell apart, a setting or a plan's
step outside the shaker's limits are refused in one line that names them.

The loop runs on the virtual rig (the project's own model): it checks the pipeline, not
which cause is named.  Its report is the hand-made one of :mod:`tests.suggest.reports`
(one pair of explanations, known to differ only where the drive reaches the barrier)
rather than the first record's own analysis: that takes half a minute more, and what
competes in it would depend on what the virtual rig's short record shows.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from analysis.experiment_plan import read_plan
from analysis.hdf5_records import read_recording_arrays
from rig.cli import main
from tests.suggest.reports import contact_pair_report, nothing_named_report, write_report

SEARCH = ["--frequency-hz", "2", "--amplitude-mm", "0.6:3:2", "--draws", "2", "--best", "1",
          "--settle", "2", "--dwell", "3"]


def error_line(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_loop_on_the_virtual_rig_first_record_plan_and_both_analysed(
        tmp_path: Path, capsys) -> None:
    first = tmp_path / "first.h5"  # at the report's drive
    assert main(["record", "--sim", "--drive-hz", "2", "--amplitude-mm", "1", "--duration",
                 "3", "--settle", "1", "--fs", "500", "--out", str(first), "--quiet"]) == 0
    report = write_report(tmp_path / "run.report.json")
    plan_path = tmp_path / "next.toml"
    assert main(["suggest", str(report), *SEARCH, "--out", str(plan_path), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "barrier_offset vs contact_exponent" in printed
    assert "1. 2 Hz, 3 mm: separation" in printed  # only the drive that reaches the barrier
    plan = read_plan(plan_path)
    assert [(s.frequency_hz, s.amplitude_m, s.settle_s, s.dwell_s) for s in plan.steps] == \
        [(2.0, 3e-3, 2.0, 3.0)]
    assert plan.made_by == "impact-rig suggest" and plan.source == str(report)
    made = json.loads(tomllib.loads(plan_path.read_text())["provenance"])
    assert made["command_line"][:2] == ["impact-rig", "suggest"]
    # not written over
    assert main(["suggest", str(report), *SEARCH, "--out", str(plan_path)]) == 2
    assert "already exists" in error_line(capsys)

    out = tmp_path / "next.h5"
    assert main(["sweep", "--sim", "--plan", str(plan_path), "--fs", "500", "--out", str(out),
                 "--quiet"]) == 0
    arrays = read_recording_arrays(out)
    (step,) = arrays.steps
    assert (step["direction"], step["complete"]) == (0, True)
    assert step["frequency_hz"] == pytest.approx(2.0)
    assert step["amplitude_m"] == pytest.approx(3e-3)
    rate = 1.0 / np.median(np.diff(arrays.time_s))
    assert (step["dwell_start_index"] - step["settle_start_index"]) / rate == \
        pytest.approx(2.0, abs=0.05)
    assert (step["dwell_end_index"] - step["dwell_start_index"]) / rate == \
        pytest.approx(3.0, abs=0.05)

    # both records together: one rig, the first record's step then the plan's
    joint = tmp_path / "joint.json"
    assert main(["analyze", str(first), str(out), "--json", str(joint), "--workers", "1",
                 "--quiet"]) == 0
    analysed = json.loads(joint.read_text())
    assert analysed["kind"] == "sweep"
    sweep = analysed["sweep"]
    assert sweep["source"] == f"{first}, {out}"
    assert [(s["step"], s["frequency_hz"], s["amplitude_m"]) for s in sweep["steps"]] == \
        [(0, pytest.approx(2.0), pytest.approx(1e-3)), (1, pytest.approx(2.0),
                                                        pytest.approx(3e-3))]
    assert [s["settle_s"] for s in sweep["steps"]] == pytest.approx([0.0, 2.0], abs=0.05)
    assert not sweep["set_aside"]
    assert {"omega_rad_s", "zeta"} <= set(sweep["shared"])


def test_a_report_naming_nothing_gives_a_plan_against_the_baseline(
        tmp_path: Path, capsys) -> None:
    report = write_report(tmp_path / "none.json", nothing_named_report())
    plan_path = tmp_path / "next.toml"
    assert main(["suggest", str(report), *SEARCH, "--out", str(plan_path), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert ("baseline vs contact_exponent: nothing named; the best-ranked candidate "
            "contact_exponent against the baseline") in printed
    assert "1. 2 Hz, 3 mm: separation" in printed  # only the drive that reaches the barrier
    plan = read_plan(plan_path)
    assert [(s.frequency_hz, s.amplitude_m) for s in plan.steps] == [(2.0, 3e-3)]
    assert plan.steps[0].why.startswith("baseline vs contact_exponent: separation")
    (row,) = tomllib.loads(plan_path.read_text())["suggestion"]
    assert row["pair"] == ["baseline", "contact_exponent"]


def test_a_report_with_no_candidate_at_all_is_one_line(tmp_path: Path, capsys) -> None:
    report = write_report(tmp_path / "none.json", named="none", indistinct=False,
                          ranked=False)
    assert main(["suggest", str(report), "--out", str(tmp_path / "p.toml")]) == 2
    line = error_line(capsys)
    assert line.startswith(f"impact-rig suggest: error: {report}: no competing explanations")
    assert not (tmp_path / "p.toml").exists()


def test_a_setting_outside_the_shaker_limits_is_refused(tmp_path: Path, capsys) -> None:
    report = write_report(tmp_path / "run.report.json")
    assert main(["suggest", str(report), "--frequency-hz", "2", "--amplitude-mm", "1:20:2",
                 "--out", str(tmp_path / "p.toml")]) == 2
    line = error_line(capsys)
    assert "setting 2 Hz, 20 mm:" in line and "outside the configured limits" in line


def test_a_plan_step_outside_the_shaker_limits_is_refused_by_its_number(
        tmp_path: Path, capsys) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text("[[step]]\nfrequency_hz = 2.0\namplitude_m = 0.001\nsettle_s = 1.0\n"
                    "dwell_s = 2.0\n\n[[step]]\nfrequency_hz = 2.0\namplitude_m = 0.05\n"
                    "settle_s = 1.0\ndwell_s = 2.0\n")
    out = tmp_path / "never.h5"
    assert main(["sweep", "--sim", "--plan", str(plan), "--out", str(out)]) == 2
    line = error_line(capsys)
    assert f"{plan}: step 2 (2 Hz, 50 mm):" in line and "outside the configured limits" in line
    assert not out.exists()


def test_a_plan_does_not_mix_with_a_sweeps_settings(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text("[[step]]\nfrequency_hz = 2.0\namplitude_m = 0.001\nsettle_s = 1.0\n"
                    "dwell_s = 2.0\n")
    assert main(["sweep", "--sim", "--plan", str(plan), "--dwell", "9",
                 "--out", str(tmp_path / "x.h5")]) == 2
    assert "the plan's steps set the drive; drop --dwell" in error_line(capsys)


def test_the_default_grid_leaves_out_what_the_limits_forbid_and_says_so(
        tmp_path: Path, capsys) -> None:
    report = tmp_path / "big.json"
    content = contact_pair_report()
    content["drive"]["stated"]["amplitude_m"] = 6e-3  # the default grid reaches 12 mm
    report.write_text(json.dumps(content))
    assert main(["suggest", str(report), "--draws", "0", "--settle", "1", "--dwell", "1",
                 "--out", str(tmp_path / "p.toml"), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "left out 5 setting(s) of the default grid that the shaker limits" in printed
    assert "1.2 Hz 12 mm" in printed and "2.8 Hz 12 mm" in printed
