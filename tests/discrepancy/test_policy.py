"""The rules that decide what is named are one object: the analysis reads them from it, the
report states them, and a command line can change them with a one-line error for a bad one.

The decay is drawn by the reference simulator (``reference/free_decays.py``: scipy
DOP853, not the project's integrator); the analysis sees one CSV and its JSON sidecar.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

from analysis.discrepancy import DEFAULT_POLICY, SelectionPolicy, analyze_record
from analysis.record_loaders import load_record
from reference.free_decays import draw_free_decay


def test_every_rule_has_a_reason_and_bad_values_are_named():
    rules = DEFAULT_POLICY.as_json()
    for f in dataclasses.fields(SelectionPolicy):
        assert rules[f.name]["value"] == getattr(DEFAULT_POLICY, f.name)
        assert len(rules[f.name]["why"]) > 20, f.name
    assert rules["residual_reading"]["min_structure"]["value"] > 0
    assert rules["term_proposal"]["min_gain"]["value"] > 0
    with pytest.raises(ValueError, match="max_causes"):
        SelectionPolicy(max_causes=0)
    with pytest.raises(ValueError, match="indistinct_correlation"):
        SelectionPolicy(indistinct_correlation=1.2)
    with pytest.raises(ValueError, match=r"max_causes = 2\.5: a whole number"):
        SelectionPolicy(max_causes=2.5)
    with pytest.raises(ValueError, match="no rule bic"):
        DEFAULT_POLICY.with_values(bic=3.0)
    assert SelectionPolicy.from_assignments(["bic_margin=6", "max_causes = 2"]).changed() == {
        "bic_margin": 6.0, "max_causes": 2}
    with pytest.raises(ValueError, match="'max_causes=two': 'two' is not a whole number"):
        SelectionPolicy.from_assignments(["max_causes=two"])
    with pytest.raises(ValueError, match="expected NAME=VALUE"):
        SelectionPolicy.from_assignments(["bic_margin"])


@pytest.fixture(scope="module")
def friction_decay(tmp_path_factory):
    """A free decay with dry friction at the pivot (seed 8904: named under the default rules
    by test_decay_pairs)."""
    decay = draw_free_decay(8904, ("coulomb_friction",))
    return decay, load_record(decay.write(tmp_path_factory.mktemp("friction")))


def test_the_report_states_its_rules_and_the_rules_decide(friction_decay):
    _decay, record = friction_decay
    default = analyze_record(record, workers=1).as_json()
    assert [c["cause"] for c in default["causes"]] == ["coulomb_friction"]
    assert default["policy"]["bic_margin"]["value"] == DEFAULT_POLICY.bic_margin
    gain = default["causes"][0]["gain"]["information_criterion_delta"]
    # a margin above the cause's own gain: the same fits, and nothing may be named
    strict = SelectionPolicy(bic_margin=2.0 * gain)
    report = analyze_record(record, workers=1, policy=strict).as_json()
    assert report["causes"] == [] and report["cause"] == "none", report["causes"]
    assert report["policy"]["bic_margin"]["value"] == 2.0 * gain
    assert all(not row["earns_keep"] for row in report["ranking"])


def test_a_bad_rule_on_the_command_line_is_one_line_naming_it(friction_decay, tmp_path):
    decay, _ = friction_decay
    csv = decay.write(tmp_path)
    result = subprocess.run(
        [sys.executable, "-m", "rig.cli", "analyze", str(csv), "--rule", "bic_margn=6"],
        capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "bic_margn=6" in lines[0] and "bic_margin" in lines[0], lines
