"""A chaotic forced record is judged on invariant statistics, and the analysis still names a
hidden cause that moves them (or none).

The records are paper case i (beta = 0.120 at 10 Hz) on the virtual rig, recorded after the
transient, with the rig's impact decay beside them; the cause's size, noise, rate, length and
start come from a seeded draw in ``hidden_cause``, and the files say only what a lab knows.
"""

from __future__ import annotations

import pytest

from analysis.discrepancy import analyze_record
from analysis.discrepancy.analyze import priors_from_decays
from analysis.records import load_record
from tests.discrepancy.hidden_cause import (
    draw_chaotic_case,
    write_case,
    write_companion_decay,
)

CASES = (("none", 616), ("excitation_amplitude", 612), ("barrier_offset", 614))


@pytest.mark.parametrize(("cause_name", "seed"), CASES)
def test_chaotic_record_names_the_cause_from_its_invariants(cause_name, seed, tmp_path):
    case = draw_chaotic_case(seed, cause_name)
    path = write_case(case, tmp_path, name="record")
    decay = write_companion_decay(case, tmp_path, name="impacts")
    text = path.with_suffix(".json").read_text() + decay.with_suffix(".json").read_text()
    for word in ("eps", "theta_b", "barrier", "excitation", "chaotic"):
        assert word not in text
    priors = priors_from_decays(impact_decay=load_record(decay))
    report = analyze_record(load_record(path), workers=1, priors=priors).as_json()
    assert report["chaos_01_K"] > 0.8
    assert report["comparison"] == "invariant statistics"
    assert all(row["invariant_ratio"] is not None for row in report["ranking"])
    assert report["cause"] == case.cause, report["ranking"][:3]
    if case.cause == "none":
        assert report["extended"]["rms_residual"] == report["baseline"]["rms_residual"]
        return
    best = report["ranking"][0]
    assert best["cause"] == case.cause
    for key, truth in case.values.items():
        assert best["parameters"][key]["value"] == pytest.approx(truth, rel=0.1)
    assert best["invariant_ratio"] < 0.7
