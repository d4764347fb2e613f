"""A free decay whose backbone no named cause gives is flagged, and says why.

The decays are drawn by the reference simulator (``reference/free_decays.py``: scipy
DOP853, not the project's integrator): a pendulum with a cubic hairspring at its pivot, an
effect outside the registry whose stiffening changes how the frequency follows the swing,
and a clean pendulum.  The analysis sees one CSV and its JSON sidecar, as a lab writes them.
"""

from __future__ import annotations

import math

import pytest

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.free_decays import draw_free_decay


@pytest.mark.parametrize(("seed", "spring"), [(8801, 1), (8802, -1)],
                         ids=["stiffening", "softening"])
def test_a_hairspring_shows_as_the_decays_backbone_and_leaves_it_unexplained(
    seed, spring, tmp_path
):
    decay = draw_free_decay(seed, spring=spring)
    report = analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()
    backbone = [f for f in report["residual_findings"] if f["kind"] == "backbone"]
    assert report["unexplained"], report["residual_findings"]
    assert len(backbone) == 1, report["residual_findings"]
    # a stiffening spring (c3 > 0) raises the frequency at large swings, against gravity's
    # softening: the record's frequency rises less than the model's as the swing decays
    # (mismatch < 0), and the other way for a spring that softens
    assert math.copysign(1.0, backbone[0]["mismatch"]) == -math.copysign(1.0, decay.c3_per_s2)


def test_a_clean_decay_has_no_backbone_finding(tmp_path):
    decay = draw_free_decay(8803)
    report = analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()
    assert report["cause"] == "none"
    assert not [f for f in report["residual_findings"] if f["kind"] == "backbone"]
