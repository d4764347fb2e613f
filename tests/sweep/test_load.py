"""Sweeps read from a recording, an exported sweep CSV and per-step files: the same steps,
steps that cannot be judged set aside with the reason, bad files refused in one line."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from analysis.exchange import read_meta, sidecar_path
from analysis.record_loaders import is_sweep
from analysis.sweep.load import SweepFormatError, load_sweep
from reference.sweeps import write_marked_recording
from rig.cli import main
from tests.sweep.recordings import sine_sweep

FS = 500.0
AMPLITUDES = (1e-3, 2e-3, 3e-3, 2e-3)


def _recording(tmp_path: Path, name: str = "sweep.h5", **options) -> Path:
    complete = options.pop("complete", None)
    angle, edges, marks = sine_sweep(AMPLITUDES, fs=FS, complete=complete)
    marks = options.pop("marks", marks)
    edges = options.pop("edges", edges)
    return write_marked_recording(tmp_path / name, angle, FS, edges, marks,
                                 table=1e-3 * angle, **options)


def test_recording_steps_are_the_dwells_with_their_settings(tmp_path: Path) -> None:
    path = _recording(tmp_path)
    assert is_sweep([path])
    sweep = load_sweep([path])
    assert sweep.parameter == "amplitude" and not sweep.set_aside
    assert [s.number for s in sweep.steps] == [0, 1, 2, 3]
    assert [s.amplitude_m for s in sweep.steps] == list(AMPLITUDES)
    for step in sweep.steps:
        record = step.record
        assert step.settle_s == pytest.approx(1.0)
        assert record.time_s[-1] - record.time_s[0] == pytest.approx(3.0 - 1 / FS)
        assert record.time_s[0] == pytest.approx(4.0 * step.number + 1.0)
        assert record.drive["amplitude_m"] == step.amplitude_m
        assert record.table_m is not None and record.tach_indices.size == 15


def test_exported_sweep_csv_and_per_step_files_give_the_same_steps(tmp_path: Path) -> None:
    path = _recording(tmp_path)
    assert main(["export", str(path), "--out", str(tmp_path / "whole.csv")]) == 0
    assert main(["export", str(path), "--out", str(tmp_path / "each.csv"), "--per-step"]) == 0
    steps = read_meta(sidecar_path(tmp_path / "whole.csv")).extra["sweep_steps"]
    assert [s["direction"] for s in steps] == [1, 1, 1, 1]
    from_recording = load_sweep([path])
    from_csv = load_sweep([tmp_path / "whole.csv"])
    per_step = sorted(tmp_path.glob("each_step*.csv"))
    from_files = load_sweep(per_step)
    assert from_files.parameter == from_csv.parameter == "amplitude"
    for a, b, c in zip(from_recording.steps, from_csv.steps, from_files.steps, strict=True):
        assert a.amplitude_m == b.amplitude_m == c.amplitude_m
        assert b.settle_s == pytest.approx(a.settle_s)
        for other in (b, c):
            np.testing.assert_allclose(other.record.angle_rad, a.record.angle_rad, atol=1e-7)
            np.testing.assert_array_equal(other.record.tach_indices, a.record.tach_indices)


def test_interrupted_step_is_set_aside_and_the_sweep_kept_to_it(tmp_path: Path) -> None:
    path = _recording(tmp_path, complete=[True, True, True, False])
    sweep = load_sweep([path])
    assert [s.number for s in sweep.steps] == [0, 1, 2]
    assert [(s.number, s.reason.split(":")[0]) for s in sweep.set_aside] == [(3, "interrupted")]


def test_a_step_interrupted_before_its_dwell_began_is_set_aside(tmp_path: Path) -> None:
    *_, marks = sine_sweep(AMPLITUDES, fs=FS, complete=[True, True, True, False])
    settle = marks[3].settle_start_index  # stopped while settling: an empty dwell
    marks[3] = replace(marks[3], dwell_start_index=settle, dwell_end_index=settle)
    path = _recording(tmp_path, marks=marks)
    sweep = load_sweep([path])
    assert [s.number for s in sweep.steps] == [0, 1, 2]
    assert [(s.number, s.reason.split(":")[0]) for s in sweep.set_aside] == [(3, "interrupted")]


def test_short_step_and_lost_samples_are_set_aside(tmp_path: Path) -> None:
    angle, edges, marks = sine_sweep(AMPLITUDES, fs=FS)
    # step 1's dwell cut to 1 s; samples of step 2's dwell lost
    marks[1] = replace(marks[1], dwell_end_index=marks[1].dwell_start_index + 500)
    path = write_marked_recording(tmp_path / "s.h5", angle, FS, edges, marks,
                                 lost=(5000, 5200))
    sweep = load_sweep([path])
    assert [s.number for s in sweep.steps] == [0, 3]
    reasons = {s.number: s.reason for s in sweep.set_aside}
    assert reasons[1].startswith("too short to judge: a dwell of 1 s")
    assert reasons[2].startswith("lost samples: 200 of its dwell's 1500")


@pytest.mark.parametrize(("change", "message"), [
    ("none", "no sweep steps"),
    ("overlap", "sweep step 2 overlaps step 1"),
    ("no_tach", "sweep step 1: no tach edges in its dwell"),
    ("all_interrupted", "no step to analyse (step 0: interrupted"),
])
def test_bad_sweep_file_is_refused_in_one_line(tmp_path: Path, change: str,
                                              message: str) -> None:
    angle, edges, marks = sine_sweep(AMPLITUDES, fs=FS)
    if change == "none":
        # a recording without marks is no sweep; asked to load one as a sweep it is refused
        path = write_marked_recording(tmp_path / "s.h5", angle, FS, edges, marks[:1])
        import h5py
        with h5py.File(path, "a") as f:
            f["sweep_steps"].resize((0,))
    else:
        if change == "overlap":
            marks[2] = replace(marks[2], settle_start_index=marks[1].dwell_end_index - 100)
        elif change == "no_tach":
            edges = edges[(edges < marks[1].settle_start_index)
                          | (edges >= marks[1].dwell_end_index)]
        else:
            marks = [replace(m, complete=False) for m in marks]
        path = write_marked_recording(tmp_path / "s.h5", angle, FS, edges, marks)
    with pytest.raises(SweepFormatError) as error:
        load_sweep([path])
    text = str(error.value)
    assert message in text and "\n" not in text and text.count(str(path)) == 1


def test_a_step_that_cannot_be_fitted_is_set_aside_with_the_reason(tmp_path: Path) -> None:
    """A step that is no forced record fit for a fit is named with the reason, and the
    sweep goes on without it (a lone step's fit once failed the whole sweep)."""
    from analysis.sweep.fit import StepsNotIdentifiedError, sweep_data

    sweep = load_sweep([_recording(tmp_path)])
    steps = list(sweep.steps)
    steps[1] = replace(steps[1], record=replace(steps[1].record, experiment="free_decay"))
    broken = replace(sweep, steps=tuple(steps))
    with pytest.raises(StepsNotIdentifiedError) as failed:
        sweep_data(broken)
    assert list(failed.value.reasons) == [1]
    assert "not a forced one" in failed.value.reasons[1]
    kept = broken.setting_aside(failed.value.reasons)
    assert [s.number for s in kept.steps] == [0, 2, 3]
    assert [(a.number, a.reason) for a in kept.set_aside] == [(1, failed.value.reasons[1])]
    assert len(sweep_data(kept).steps) == 3
    with pytest.raises(ValueError, match="no step to analyse"):
        kept.setting_aside({0: "a", 2: "b", 3: "c"})


def test_a_record_and_a_sweep_given_together_are_one_sweep(tmp_path: Path) -> None:
    """A forced record and the recording of the steps planned after it (``impact-rig
    suggest``, ``sweep --plan``) are one sweep: the record's step, then the recording's,
    numbered in running order over both, each with its own setting and settle."""
    first = _recording(tmp_path, "first.h5")
    assert main(["export", str(first), "--out", str(tmp_path / "one.csv"), "--per-step"]) == 0
    record = sorted(tmp_path.glob("one_step*.csv"))[1]  # the 2 mm step, as a record alone
    later = _recording(tmp_path, "later.h5", complete=[True, True, True, False])
    sweep = load_sweep([record, later])
    assert [s.number for s in sweep.steps] == [0, 1, 2, 3]
    assert [s.amplitude_m for s in sweep.steps] == [2e-3, *AMPLITUDES[:3]]
    assert [s.settle_s for s in sweep.steps] == pytest.approx([0.0, 1.0, 1.0, 1.0])
    assert [(s.number, s.reason.split(":")[0]) for s in sweep.set_aside] == \
        [(4, "interrupted")]
    assert str(later) in sweep.set_aside[0].reason
    alone = load_sweep([later])
    np.testing.assert_array_equal(sweep.steps[1].record.angle_rad,
                                  alone.steps[0].record.angle_rad)
