"""A decay whose misfit no named cause explains is flagged, with the finding that says what
kind of term is missing and the term itself; a decay with unusual but structureless noise
names nothing.

The decays are drawn by the reference simulator (``reference/decays.py``: scipy
DOP853, not the project's integrator); each seed is the decay benchmark's draw of that
effect (7000 + 53 i).  The analysis sees one CSV and its JSON sidecar.
"""

from __future__ import annotations

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.decays import EFFECTS, draw_effect_decay
from tests.tolerance import Z_95, Z_999


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
    half = (high - low) / 2.0 * Z_999 / Z_95
    assert abs(terms[0]["coefficient"] + truth["c3_per_s2"]) <= half, (truth, terms[0])
    assert "theta^3" not in {c["cause"] for c in report["causes"]}


def test_structureless_heavy_tailed_noise_names_no_cause(tmp_path):
    report = _report("noise_decoy_free", tmp_path)
    assert report["causes"] == [] and report["cause"] == "none", report["causes"]
    assert not report["unexplained"], report["residual_reading"]["why"]


def test_a_contact_damping_on_the_penetration_is_flagged_as_parameters_that_change_with_the_swing(
        tmp_path):
    # contact damping K mu0' delta delta' instead of Hunt-Crossley's K mu0 delta^1.5 delta':
    # the whole record's residual is white, but Hunt-Crossley's mu0 fitted on the deep early
    # impacts and on the shallow late ones differ, and in the direction the law says (a
    # damping on delta loses relatively more than one on delta^1.5 where the impact is
    # shallow, so the late impacts ask for a larger mu0)
    report = _report("contact_damping_on_delta", tmp_path)
    assert report["unexplained"], report["residual_reading"]["why"]
    found = [f for f in report["residual_findings"] if f["kind"] == "constancy"]
    assert found, report["residual_findings"]
    assert found[0]["z_mu0_s_per_m"] <= -found[0]["z_needed"], found[0]


def test_a_damping_that_grows_with_the_angle_is_proposed_with_its_size(tmp_path):
    # theta'' -= d21 theta^2 theta': the drag named in its place is not the whole story; the
    # term is proposed within its 99.9 % interval of the truth
    report, truth = _report_and_truth("angle_rate_damping", tmp_path)
    assert report["unexplained"], report["residual_reading"]["why"]
    terms = {t["term"]: t for t in report["proposed_terms"] if t["region"] == "flight"}
    assert "theta^2 theta'" in terms, report["proposed_terms"]
    term = terms["theta^2 theta'"]
    half = (term["ci95"][1] - term["ci95"][0]) / 2.0 * Z_999 / Z_95
    assert abs(term["coefficient"] + truth["d21_per_rad2_s"]) <= half, (truth, term)


def test_a_cubic_damping_is_proposed_or_listed_as_a_term_the_record_cannot_tell_apart(tmp_path):
    # theta'' -= d3 theta'^3: over a decay's swings theta'^3 and theta^2 theta' share their
    # first harmonic; the report proposes one and lists the other beside it
    report = _report("cubic_rate_damping", tmp_path)
    assert report["unexplained"], report["residual_reading"]["why"]
    flight = [t for t in report["proposed_terms"] if t["region"] == "flight"]
    offered = {t["term"] for t in flight} | {a for t in flight for a in t["alternatives"]}
    assert "theta'^3" in offered, report["proposed_terms"]
    assert "theta'^3" not in {c["cause"] for c in report["causes"]}


def test_a_contact_damping_on_the_squared_penetration_is_not_explained_as_dry_friction(tmp_path):
    # contact damping K mu0' delta^2 delta': dry friction fits it with a large information
    # gain only by taking all of the rig's viscous damping (zeta on its bound 0), which no
    # real pendulum can lack; the record is flagged, never explained by friction
    report = _report("contact_damping_on_delta2", tmp_path)
    assert "coulomb_friction" not in {c["cause"] for c in report["causes"]}, report["causes"]
    assert report["unexplained"], report["residual_reading"]["why"]
    kinds = {f["kind"] for f in report["residual_findings"]}
    assert kinds & {"constancy", "implausible_gain"}, report["residual_findings"]
