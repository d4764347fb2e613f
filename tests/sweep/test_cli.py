"""``impact-rig analyze`` given a sweep's files: a bad sweep is refused in one line naming
the file once and the step, and an error from below names the analysed file once."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from reference.sweeps import write_marked_recording
from rig.cli import main
from tests.sweep.recordings import sine_sweep


def test_overlapping_steps_are_one_line_naming_file_and_step(tmp_path: Path, capsys) -> None:
    angle, edges, marks = sine_sweep((1e-3, 2e-3, 3e-3))
    marks[2] = replace(marks[2], settle_start_index=marks[1].dwell_end_index - 50)
    path = write_marked_recording(tmp_path / "overlap.h5", angle, 500.0, edges, marks)
    assert main(["analyze", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"impact-rig analyze: error: {path}: sweep step 2 overlaps "
                               "step 1")
    assert lines[0].count(str(path)) == 1


def test_forced_record_without_amplitude_names_its_path_once(tmp_path: Path, capsys) -> None:
    t = np.arange(3000) / 500.0
    csv = tmp_path / "forced.csv"
    csv.write_text("time_s,angle_rad,tach\n" + "".join(
        f"{x:.4f},{0.05 * np.sin(2 * np.pi * 5 * x):.6f},{int(k % 100 == 0)}\n"
        for k, x in enumerate(t)))
    (tmp_path / "forced.json").write_text(json.dumps(
        {"experiment": "forced", "rig": {}, "drive": {"frequency_hz": 5.0}}))
    assert main(["analyze", str(csv), "--workers", "1"]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line == (f"impact-rig analyze: error: {csv}: cannot analyse: a forced record needs "
                    "drive.amplitude_m > 0 in its metadata (docs/MODEL.md section 5)")
