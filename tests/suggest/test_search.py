"""The search finds the drive settings where two explanations predict different records, and
ranks them first: a barrier with Hertz contact against one with a soft contact law, the same
wherever the pendulum stays clear of the barrier (tests/suggest/reports.py says where that
is, analytically)."""

from __future__ import annotations

import pickle
from typing import Any

import pytest

from analysis.suggest import (
    ReportError,
    competing_pairs,
    report_rig,
    search,
    settings_grid,
    weak_finding,
)
from tests.suggest.reports import (
    BIC_MARGIN,
    FS_HZ,
    GAP_RAD,
    NOISE_RAD,
    contact_pair_report,
    nothing_named_report,
    reaches_barrier,
)

FREQUENCY_HZ = 2.0
AMPLITUDES_M = (0.3e-3, 0.6e-3, 3e-3, 4e-3)


def run_search(amplitudes_m=AMPLITUDES_M, run_map=None):
    report = contact_pair_report()
    pairs = competing_pairs(report, "report.json")
    settings = settings_grid([FREQUENCY_HZ], amplitudes_m, settle_s=10.0, dwell_s=10.0)
    return search(pairs, report_rig(report, "report.json"), settings, noise_rad=NOISE_RAD,
                  sample_rate_hz=FS_HZ, draws=4, run_map=run_map)


@pytest.fixture(scope="module")
def searched():
    return run_search()


def test_the_settings_that_reach_the_barrier_are_ranked_first(searched) -> None:
    impacting = {a for a in AMPLITUDES_M if reaches_barrier(FREQUENCY_HZ, a)}
    clear = {a for a in AMPLITUDES_M if reaches_barrier(FREQUENCY_HZ, a) is False}
    assert impacting == {3e-3, 4e-3} and clear == {0.3e-3, 0.6e-3}  # the oracle's split
    (result,) = searched
    ranked = [s.setting.amplitude_m for s in result.ranked]
    assert set(ranked[:2]) == impacting, ranked
    assert [s.setting.amplitude_m for s in result.best(3)] == ranked[:2]
    for s in result.ranked[:2]:
        assert s.result.separation > 1.0  # beyond both spreads, by more than the noise
        assert s.expected_bic_difference is None or s.expected_bic_difference > 100


def test_where_the_barrier_is_never_reached_the_two_predict_the_same_record(searched) -> None:
    (result,) = searched
    for s in result.ranked[2:]:
        assert reaches_barrier(FREQUENCY_HZ, s.setting.amplitude_m) is False
        assert s.result.distance == 0.0  # the same equations in flight, the same numbers
        assert s.result.separation < 0  # only the intervals' own spread is left
        assert s.result.regime_first == s.result.regime_second == "period-1"


def test_the_draws_are_the_same_wherever_they_are_made() -> None:
    (pair,) = competing_pairs(contact_pair_report(), "r")
    first = pair.first.draws(3, (37, 0))
    assert first == pair.first.draws(3, (37, 0))
    for drawn in first:
        for key, (low, high) in pair.first.intervals.items():
            assert low <= drawn[key] <= high


def test_a_named_cause_is_set_against_its_runner_up() -> None:
    (pair,) = competing_pairs(contact_pair_report(indistinct=False), "r")
    assert (pair.first.name, pair.second.name) == ("barrier_offset", "contact_exponent")
    assert "runner-up" in pair.why


def test_a_report_naming_nothing_sets_the_best_ranked_candidate_against_the_baseline(
        ) -> None:
    report = nothing_named_report()
    (pair,) = competing_pairs(report, "r")  # the second ranked beyond the BIC margin
    assert (pair.first.name, pair.second.name) == ("baseline", "contact_exponent")
    assert pair.why == ("nothing named; the best-ranked candidate contact_exponent against "
                        "the baseline")
    baseline, soft = pair.first, pair.second
    assert baseline.causes == () and soft.causes == ("contact_exponent",)
    # each with its fitted values, and intervals where the report gives them
    assert baseline.theta_b_rad == soft.theta_b_rad == GAP_RAD
    assert soft.values["n"] == 2.5 and soft.intervals["n"] == pytest.approx((2.45, 2.55))
    assert "n" not in baseline.values and "K_n" not in soft.intervals
    assert set(baseline.intervals) == set(soft.intervals) - {"n", "theta_b_rad"}


def test_candidates_ranked_within_the_margin_of_the_best_face_the_baseline_and_each_other(
        ) -> None:
    pairs = competing_pairs(nothing_named_report(second_score=5.0 - BIC_MARGIN), "r")
    assert [(p.first.name, p.second.name) for p in pairs] == [
        ("baseline", "contact_exponent"), ("baseline", "barrier_offset"),
        ("contact_exponent", "barrier_offset")]
    assert "within the BIC margin" in pairs[1].why
    assert pairs[2].why == "barrier_offset ranked within the BIC margin of contact_exponent"


def weakly_named_report(**flags: Any) -> dict[str, Any]:
    """A report naming the barrier offset, its contact-law runner-up ranked far behind,
    flagged by ``flags`` (report keys)."""
    report = contact_pair_report(indistinct=False)
    report["ranking"][1]["score"] = 120.0 - 5 * BIC_MARGIN
    report["policy"]["heldout_ratio"] = {"value": 0.95, "why": "as analyze's default"}
    report["causes"] = [{"cause": "barrier_offset",
                         "gain": {"information_criterion_delta": 120.0,
                                  "heldout_ratio": 0.5}}]
    return report | flags


@pytest.mark.parametrize(("flags", "why"), [
    ({"unexplained": True}, "the report says the model still misses something"),
    ({"warnings": ["theta_b_rad on its bound"]},
     "the report warns: theta_b_rad on its bound"),
    ({"causes": [{"cause": "barrier_offset", "gain": {"heldout_ratio": 0.97}}]},
     "its held-out error x0.97, short of the clear gain (x0.95 or less)"),
])
def test_a_weak_finding_sets_the_named_cause_against_the_baseline(
        flags: dict[str, Any], why: str) -> None:
    report = weakly_named_report(**flags)
    assert weak_finding(report) == why
    runner_up, weak = competing_pairs(report, "r")
    assert (runner_up.first.name, runner_up.second.name) == ("barrier_offset",
                                                             "contact_exponent")
    assert (weak.first.name, weak.second.name) == ("barrier_offset", "baseline")
    assert weak.first.causes == ("barrier_offset",) and weak.second.causes == ()
    assert weak.why == f"barrier_offset is named, weakly ({why}); against the baseline"


def test_a_finding_the_report_does_not_flag_is_not_set_against_the_baseline() -> None:
    report = weakly_named_report()  # held-out error x0.5, nothing unexplained or warned
    assert weak_finding(report) is None
    assert [(p.first.name, p.second.name) for p in competing_pairs(report, "r")] == [
        ("barrier_offset", "contact_exponent")]


def test_an_implausible_best_gives_way_to_the_best_plausible_one() -> None:
    report = nothing_named_report()
    report["ranking"][0]["implausible"] = "n on its bound"
    (pair,) = competing_pairs(report, "r")
    assert pair.second.name == "barrier_offset"


def test_a_report_with_nothing_to_tell_apart_says_so() -> None:
    report = contact_pair_report(named="none", indistinct=False, ranked=False)
    with pytest.raises(ReportError, match="no competing explanations to tell apart: no "
                       "indistinct pair, and no cause named and no candidate ranked"):
        competing_pairs(report, "r.json")


def test_the_search_finds_where_the_best_ranked_candidate_shows_against_the_baseline(
        ) -> None:
    """The baseline's Hertz barrier and the soft law at the same gap: only the drive that
    reaches the barrier separates them."""
    report = nothing_named_report()
    settings = settings_grid([FREQUENCY_HZ], (0.6e-3, 3e-3), settle_s=10.0, dwell_s=10.0)
    (result,) = search(competing_pairs(report, "r"), report_rig(report, "r"), settings,
                       noise_rad=NOISE_RAD, sample_rate_hz=FS_HZ, draws=2)
    assert [s.setting.amplitude_m for s in result.best(3)] == [3e-3]
    assert reaches_barrier(FREQUENCY_HZ, 3e-3) and reaches_barrier(FREQUENCY_HZ, 0.6e-3) \
        is False



def test_the_tasks_travel_to_a_worker_as_plain_data() -> None:
    """What a Dask worker gets (analysis.maps.MapRunner.map): the function and each task
    pickled; the figures it sends back are the ones found here."""
    calls = []

    def through_pickle(function, tasks):
        calls.append(len(tasks))
        function = pickle.loads(pickle.dumps(function))
        return [pickle.loads(pickle.dumps(function(pickle.loads(pickle.dumps(task)))))
                for task in tasks]

    amplitudes = (0.6e-3, 3e-3)
    here = run_search(amplitudes)
    there = run_search(amplitudes, through_pickle)
    assert calls == [len(amplitudes)]  # one task per setting
    assert [s.result for s in there[0].ranked] == [s.result for s in here[0].ranked]
