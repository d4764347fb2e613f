"""A decay whose misfit no named cause explains is flagged, with the finding that says what
kind of term is missing; a decay with unusual but structureless noise names nothing.

The decays are drawn by the reference simulator (``tests/reference/decays.py``: scipy
DOP853, not the project's integrator); each seed is the decay benchmark's draw of that
effect (7000 + 53 i).  The analysis sees one CSV and its JSON sidecar.
"""

from __future__ import annotations

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from tests.reference.decays import EFFECTS, draw_effect_decay


def _report(effect: str, tmp_path) -> dict:
    seed = 7000 + 53 * list(EFFECTS).index(effect)
    decay = draw_effect_decay(seed, effect)
    return analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()


def test_a_stiffening_pivot_spring_is_flagged_with_the_backbone_it_bends(tmp_path):
    report = _report("pivot_hairspring_stiffening", tmp_path)
    assert report["unexplained"], report["residual_reading"]["why"]
    backbone = [f for f in report["residual_findings"] if f["kind"] == "backbone"]
    assert backbone, report["residual_findings"]
    # a spring that stiffens with the swing raises the large swings' frequency: as the swing
    # dies the record's frequency falls, and further than any fitted named cause's
    assert backbone[0]["record_frequency_change"] < backbone[0]["model_frequency_change"]


def test_structureless_heavy_tailed_noise_names_no_cause(tmp_path):
    report = _report("noise_decoy_free", tmp_path)
    assert report["causes"] == [] and report["cause"] == "none", report["causes"]
    assert not report["unexplained"], report["residual_reading"]["why"]
