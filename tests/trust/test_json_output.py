"""The one JSON writer (analysis.json_output): strict JSON whatever the numbers, numpy values
made plain, UTF-8 text ending in a newline, and no file written over unless asked; and a
command's file that holds a number that is not finite, read back as strict JSON."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from analysis.json_output import to_json_text, write_json
from recording.metadata import read_attributes
from recording.reader import open_recording
from rig.cli import main
from tests.strict_json import strict_loads


def test_a_number_that_is_not_finite_is_written_as_null(tmp_path):
    value = {"nan": math.nan, "limits": (math.inf, -math.inf, 1.5), "numpy": np.float32("nan")}
    path = write_json(tmp_path / "report.json", value)
    assert strict_loads(path.read_text(encoding="utf-8")) == {
        "nan": None, "limits": [None, None, 1.5], "numpy": None,
    }


def test_numpy_values_are_written_as_plain_numbers_and_lists(tmp_path):
    value = {
        "count": np.int64(3),
        "gain": np.float32(0.5),
        "good": np.bool_(True),
        "section": np.array([[1.0, np.nan], [2.0, 3.0]]),
        7: "a key that is not text",
    }
    text = write_json(tmp_path / "numpy.json", value).read_text(encoding="utf-8")
    read = strict_loads(text)
    assert read == {
        "count": 3, "gain": 0.5, "good": True, "section": [[1.0, None], [2.0, 3.0]],
        "7": "a key that is not text",
    }
    assert type(read["count"]) is int and type(read["good"]) is bool


def test_a_file_is_utf8_indented_and_ends_in_a_newline_and_embedded_text_is_one_line(tmp_path):
    path = write_json(tmp_path / "notes.json", {"operator": "Zoë", "steps": [1]})
    text = path.read_bytes().decode("utf-8")
    assert text == '{\n  "operator": "Zoë",\n  "steps": [\n    1\n  ]\n}\n'
    assert to_json_text({"theta": [0.1, math.nan]}, one_line=True) == '{"theta": [0.1, null]}'


def test_an_existing_file_is_written_over_only_when_asked(tmp_path):
    path = tmp_path / "taken.json"
    path.write_text("mine", encoding="utf-8")
    with pytest.raises(FileExistsError):
        write_json(path, {"cause": "none"})
    assert path.read_text(encoding="utf-8") == "mine"
    write_json(path, {"cause": "none"}, overwrite=True)
    assert strict_loads(path.read_text(encoding="utf-8")) == {"cause": "none"}


def test_a_value_json_cannot_hold_is_refused_before_any_file_is_made(tmp_path):
    path = tmp_path / "odd.json"
    with pytest.raises(TypeError):
        write_json(path, {"odd": object()})
    assert not path.exists()


def test_a_recording_without_a_time_limit_keeps_its_plan_as_strict_json(tmp_path):
    """``record --duration inf`` runs until the swing dies away: the plan's unbounded duration
    is null in the file's extra_json, not the token Infinity that strict readers refuse."""
    path = tmp_path / "decay.h5"
    assert main([
        "record", "--sim", "--experiment", "free_decay", "--duration", "inf",
        "--stop-below-rad", "10", "--pretrigger", "0", "--out", str(path), "--quiet",
    ]) == 0  # fmt: skip
    with h5py.File(path, "r") as handle:
        plan = strict_loads(read_attributes(handle)["extra_json"])["plan"]
    assert plan["max_duration_s"] is None and plan["stop_below_rad"] == 10.0
    with open_recording(path) as recording:
        assert recording.info.extra["plan"] == plan
