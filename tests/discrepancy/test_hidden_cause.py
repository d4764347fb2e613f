"""The analysis must name a decay's one hidden cause (or none) from the files alone, with
its size.

Each decay is drawn by the independent reference simulator (``reference/decays.py``:
scipy DOP853 with events, never the project's integrator or its cause code) from a seed
that picks the rig's own parameters, the release, the noise, the rate, the length and the
cause's size; the analysis sees one CSV and its JSON sidecar, which state only what a lab
knows.  These are the impact decays' causes no pair names (``test_decay_pairs.py``) and a
clean impact decay; docs/development.md ("Which test names each cause") lists the rest.

Seeds: the range 3902-3907, one per case, every one kept.  The drag case named drag on one
BLAS thread and none on two until every decay fit held BLAS to one thread
(``analysis/identify/threads.py``): it must pass on any machine.  Miss budget: the known misses
marked below as strict expected failures (a fix shows as XPASS and fails the run, so the
mark comes off with it); the rate over a larger draw belongs to the decay benchmark.
"""

from __future__ import annotations

import pytest

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.decays import IMPACT, draw_decay
from tests.tolerance import Z_95, Z_999

pytestmark = pytest.mark.slow  # each test analyses a whole record

# name: (seed, kind of decay, the hidden causes)
CASES = {
    "impact: drag": (3902, IMPACT, ("quadratic_drag",)),
    "impact: sensor zero": (3903, IMPACT, ("sensor_offset",)),
    "impact: sensor cubic": (3904, IMPACT, ("sensor_nonlinearity",)),
    "impact: sensor lag": (3905, IMPACT, ("sensor_lag",)),
    "impact: none": (3907, IMPACT, ()),
}
KNOWN_MISSES = {
    "impact: sensor lag": "known miss: the lag is named, but its tau_s 5.18 ms for 5.41 ms "
                          "lies just outside the reported 99.9 % interval (+-0.23 ms): the "
                          "interval claims more than the fit holds",
}


def _case(name: str):
    marks = ([pytest.mark.xfail(strict=True, raises=AssertionError, reason=KNOWN_MISSES[name])]
             if name in KNOWN_MISSES else [])
    return pytest.param(name, id=name, marks=marks)


@pytest.mark.parametrize("name", [_case(name) for name in CASES])
def test_a_decays_single_cause_is_named_with_its_size(name, tmp_path):
    seed, experiment, causes = CASES[name]
    decay = draw_decay(seed, experiment, causes)
    report = analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()
    named = {entry["cause"]: entry for entry in report["causes"]}
    assert list(named) == list(causes), report["ranking"][:3]
    assert report["cause"] == (causes[0] if causes else "none")
    assert not report["unexplained"], report["residual_reading"]["why"]
    if causes:
        for cause, values in decay.causes.items():
            for key, truth in values.items():
                estimate = named[cause]["parameters"][key]
                low, high = estimate["ci95"]
                half = (high - low) / 2 * Z_999 / Z_95
                assert abs(estimate["value"] - truth) <= half, (cause, key, truth, estimate)
        assert report["gain"]["heldout_rms_extended"] < report["gain"]["heldout_rms_baseline"]
        assert report["gain"]["information_criterion_delta"] > 10
    else:
        assert report["extended"]["rms_residual"] == report["baseline"]["rms_residual"]
    # Hunt-Crossley contact (finite time, speed-dependent restitution) made these records:
    # instantaneous impacts with a constant restitution cannot match them as well
    comparison = report["restitution_comparison"]
    assert 0.0 < comparison["parameters"]["e"]["value"] < 1.0
    assert comparison["hunt_crossley_rms_residual"] < comparison["rms_residual"]
    assert comparison["hunt_crossley_heldout_rms"] < comparison["heldout_rms"]
