"""The analysis must name a hidden cause (or none) from the files alone.

Each case's cause, size, rig parameters, noise, rate and length come from a seeded
random draw in ``hidden_cause``; the analysis only sees a neutral CSV + JSON pair.
"""

from __future__ import annotations

import pytest

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from tests.discrepancy.hidden_cause import draw_case, write_case

FREE_DECAY_SEEDS = (101, 102, 103, 104, 105)
IMPACT_DECAY_SEEDS = (201, 202)


def _check(case, tmp_path):
    path = write_case(case, tmp_path, name="record")
    analysis = analyze_record(load_record(path), workers=1)
    report = analysis.as_json()
    assert report["cause"] == case.cause, (case, report["ranking"][:3])
    if case.cause != "none":
        fitted = report["ranking"][0]["parameters"]
        for key, truth in case.values.items():
            assert fitted[key]["value"] == pytest.approx(truth, rel=0.2), (key, fitted[key])
        assert report["gain"]["heldout_rms_extended"] < report["gain"]["heldout_rms_baseline"]
        assert report["gain"]["information_criterion_delta"] > 10
    else:
        assert report["extended"]["rms_residual"] == report["baseline"]["rms_residual"]
    if case.experiment == "impact_decay":
        # Records made with finite-time Hunt-Crossley contact: instantaneous impacts with a
        # constant restitution cannot match them as well (speed-dependent e, contact time).
        comparison = report["restitution_comparison"]
        assert 0.0 < comparison["parameters"]["e"]["value"] < 1.0
        assert comparison["hunt_crossley_rms_residual"] < comparison["rms_residual"]
        assert comparison["hunt_crossley_heldout_rms"] < comparison["heldout_rms"]


@pytest.mark.parametrize("seed", FREE_DECAY_SEEDS)
def test_free_decay_hidden_cause_is_named(seed, tmp_path):
    _check(draw_case(seed, "free_decay"), tmp_path)


@pytest.mark.parametrize("seed", IMPACT_DECAY_SEEDS)
def test_impact_decay_hidden_cause_is_named(seed, tmp_path):
    _check(draw_case(seed, "impact_decay"), tmp_path)


def test_files_do_not_reveal_the_cause(tmp_path):
    case = draw_case(3, "free_decay", "coulomb_friction")
    path = write_case(case, tmp_path, name="record")
    text = path.read_text() + path.with_suffix(".json").read_text()
    for word in ("coulomb", "friction", "Tc_N_m", "drag", "offset", "zeta"):
        assert word not in text
