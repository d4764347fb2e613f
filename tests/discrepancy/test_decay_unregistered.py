"""A decay whose misfit no named cause explains is flagged, with the finding that says what
kind of term is missing and the term itself; a decay with unusual but structureless noise
names nothing.

The decays are drawn by the reference simulator (``tests/reference/decays.py``: scipy
DOP853, not the project's integrator); each seed is the decay benchmark's draw of that
effect (7000 + 53 i).  The analysis sees one CSV and its JSON sidecar.
"""

from __future__ import annotations

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from tests.reference.decays import EFFECTS, draw_effect_decay

Z_999 = 3.29  # the truth lies inside the 99.9 % interval (1.96 sigma is the 95 % one)


def _report(effect: str, tmp_path) -> dict:
    seed = 7000 + 53 * list(EFFECTS).index(effect)
    decay = draw_effect_decay(seed, effect)
    return analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()


def _report_and_truth(effect: str, tmp_path) -> tuple[dict, dict[str, float]]:
    seed = 7000 + 53 * list(EFFECTS).index(effect)
    decay = draw_effect_decay(seed, effect)
    report = analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()
    return report, decay.effect_values


def test_a_stiffening_pivot_spring_is_flagged_and_its_term_proposed_with_its_size(tmp_path):
    report, truth = _report_and_truth("pivot_hairspring_stiffening", tmp_path)
    assert report["unexplained"], report["residual_reading"]["why"]
    backbone = [f for f in report["residual_findings"] if f["kind"] == "backbone"]
    assert backbone, report["residual_findings"]
    # a spring that stiffens with the swing raises the large swings' frequency: as the swing
    # dies the record's frequency falls, and further than any fitted named cause's
    assert backbone[0]["record_frequency_change"] < backbone[0]["model_frequency_change"]
    # the term the spring adds, theta'' -= c3 theta^3, is proposed alone, within its 99.9 %
    # interval of the truth, and never named a cause
    terms = report["proposed_terms"]
    assert [(t["term"], t["region"]) for t in terms] == [("theta^3", "flight")], terms
    low, high = terms[0]["ci95"]
    half = (high - low) / 2.0 * Z_999 / 1.96
    assert abs(terms[0]["coefficient"] + truth["c3_per_s2"]) <= half, (truth, terms[0])
    assert "theta^3" not in {c["cause"] for c in report["causes"]}


def test_structureless_heavy_tailed_noise_names_no_cause(tmp_path):
    report = _report("noise_decoy_free", tmp_path)
    assert report["causes"] == [] and report["cause"] == "none", report["causes"]
    assert not report["unexplained"], report["residual_reading"]["why"]
