"""The plan file: what suggest writes is what sweep --plan reads, and a bad one is refused
naming the step and the key."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from analysis.experiment_plan import (
    ExperimentPlan,
    PlanFileError,
    PlannedStep,
    read_plan,
    write_plan,
)
from analysis.output_paths import OutputPathError

PLAN = ExperimentPlan(
    (PlannedStep(9.5, 2.1e-3, 10.0, 20.0, why='a "quoted" why, and a backslash \\'),
     PlannedStep(12.0, 1e-3, 0.0, 5.0)),
    made_by="impact-rig suggest", source="run.report.json", notes="two steps",
    extra={"search": {"draws": 8, "frequencies_hz": [9.5, 12.0]},
           "suggestion": [{"pair": ["a", "b"], "separation_in_noise": 3.5}]})


def test_a_written_plan_reads_back_the_same(tmp_path: Path) -> None:
    path = write_plan(tmp_path / "plan.toml", PLAN, provenance={"software": "x"})
    read = read_plan(path)
    assert read.steps == PLAN.steps
    assert (read.made_by, read.source, read.notes) == ("impact-rig suggest",
                                                      "run.report.json", "two steps")
    assert read.extra == PLAN.extra
    assert tomllib.loads(path.read_text())["provenance"] == '{"software":"x"}'
    assert read.schedule() == [(0, 9.5, 2.1e-3, 10.0, 20.0), (0, 12.0, 1e-3, 0.0, 5.0)]


def test_a_plan_is_not_written_over_without_overwrite(tmp_path: Path) -> None:
    path = write_plan(tmp_path / "plan.toml", PLAN, provenance={})
    with pytest.raises(OutputPathError, match="already exists"):
        write_plan(path, PLAN, provenance={})
    write_plan(path, PLAN, provenance={}, overwrite=True)


@pytest.mark.parametrize(("text", "message"), [
    ("[[step]]\nfrequency_hz = 10.0\namplitude_m = 0.001\nsettle_s = 1.0\ndwel_s = 2.0\n",
     r"step 1: unknown key\(s\) \['dwel_s'\]"),
    ("[[step]]\nfrequency_hz = 10.0\namplitude_m = 0.001\nsettle_s = 1.0\n",
     "step 1: missing dwell_s"),
    ("[[step]]\nfrequency_hz = 10.0\namplitude_m = 0.001\nsettle_s = 1.0\ndwell_s = 2.0\n"
     "[[step]]\nfrequency_hz = -1.0\namplitude_m = 0.001\nsettle_s = 1.0\ndwell_s = 2.0\n",
     "step 2: frequency -1.0 Hz"),
    ("[[step]]\nfrequency_hz = 'ten'\namplitude_m = 0.001\nsettle_s = 1.0\ndwell_s = 2.0\n",
     "step 1: frequency_hz = 'ten': expected a finite number"),
    ("notes = 'no steps'\n", r"no \[\[step\]\] tables"),
    ("[[step]\n", "not a TOML plan file"),
])
def test_a_bad_plan_is_refused_naming_the_step_and_key(tmp_path: Path, text: str,
                                                        message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(PlanFileError, match=message) as caught:
        read_plan(path)
    assert str(caught.value).startswith(f"{path}: ")
