"""Forced records explained on their own: the regime judged from the data, the baseline fitted
down to the noise on a clean record, and a hidden cause named with its size.

Each record is drawn by the independent reference simulator (``reference``: scipy
DOP853 with events, not the project's integrator or virtual rig) from a seed that picks
the rig, the drive, the transient, the noise and the laser; the analysis sees one CSV and
its JSON sidecar, which say only what a lab knows (no decay records).  Together the cases
cover both of the paper's drive frequencies, periodic, period-k and chaotic motion,
measurement, contact and drive causes, with and without the laser channel.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.forced_records import draw_forced_case, draw_pair, write_forced_case
from reference.unregistered import EFFECTS, draw_unregistered_case
from tests.tolerance import within_999

pytestmark = pytest.mark.slow  # each test analyses a whole record

DURATION_S = 30.0
# name: (seed, cause, drive frequency, laser, regime asked of the generator)
CASES = {
    "clean, 2 Hz": (5201, "none", 2.0, None, None),
    "clean, chaotic": (5202, "none", 10.0, None, "chaotic"),
    "lag, 10 Hz, no laser": (5203, "sensor_lag", 10.0, False, None),
    "barrier, chaotic": (5204, "barrier_offset", 10.0, None, "chaotic"),
    "drive harmonic, 2 Hz, no laser": (5205, "excitation_distortion", 2.0, False, None),
    "sensor cubic, 10 Hz, laser": (5206, "sensor_nonlinearity", 10.0, True, None),
}


# this case goes through the command line, as a user runs it (the others call the library)
THROUGH_THE_COMMAND = "clean, 2 Hz"


def _analyse(name, tmp_path):
    seed, cause, frequency, laser, regime = CASES[name]
    case = draw_forced_case(seed, cause, frequency_hz=frequency, laser=laser, regime=regime,
                            duration_s=DURATION_S)
    path = write_forced_case(case, tmp_path)
    sidecar = path.with_suffix(".json").read_text()
    assert cause == "none" or cause not in sidecar
    if name != THROUGH_THE_COMMAND:
        return case, analyze_record(load_record(path), workers=2).as_json()
    out = tmp_path / "report.json"
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "analyze", str(path), "--json", str(out),
         "--report", str(tmp_path / "pages")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return case, json.loads(out.read_text())


def _regime_right(case, report) -> bool:
    judged = report["regime"]
    if case.regime == "chaotic":
        return judged["kind"] == "chaotic"
    return judged["kind"] == "periodic" and judged["period"] == case.period


@pytest.mark.parametrize("name", list(CASES))
def test_a_forced_record_is_explained_from_the_record_alone(name, tmp_path):
    case, report = _analyse(name, tmp_path)
    if name == THROUGH_THE_COMMAND:
        _check_the_command_output(case, report, tmp_path)
    assert _regime_right(case, report), (case.regime_truth, report["regime"]["label"])
    assert report["comparison"] == (
        "invariant statistics" if case.regime == "chaotic" else "point by point")
    noise = case.measurement.angle_noise_rad
    assert report["cause"] == case.cause, report["ranking"][:3]
    # and nothing beside it: the forward selection adds no cause the record lacks
    assert [c["cause"] for c in report["causes"]] == ([] if case.cause == "none"
                                                      else [case.cause])
    # the final model leaves white noise, and the residual shows nothing; the tach's drive,
    # parts in 1e4 off the stated one, is reported with the true frequency
    assert report["unexplained"] is False, report["residual_reading"]["why"]
    for finding in report["residual_findings"]:
        assert finding["kind"] == "drive_frequency", finding
        assert finding["measured_frequency_hz"] == pytest.approx(case.drive.frequency_hz,
                                                                 rel=2e-5)
    if case.cause == "none":
        # the baseline explains a clean record down to its noise, and nothing is named
        assert report["baseline"]["rms_residual"] < 1.5 * noise
        assert report["extended"]["rms_residual"] == report["baseline"]["rms_residual"]
        return
    best = next(r for r in report["ranking"] if r["cause"] == case.cause)
    for key, truth in case.causes[case.cause].items():
        assert within_999(best["parameters"][key], truth), (key, truth, best["parameters"][key])
    assert report["gain"]["heldout_rms_extended"] < report["gain"]["heldout_rms_baseline"]
    assert report["extended"]["rms_residual"] < 1.5 * noise


# one cause on a short record, the laser and the regime drawn: seeds 3911-3915, one per
# cause, every one kept; miss budget: the known miss below, a strict expected failure.  The
# pivot and sensor causes on 10 s at 10 Hz; the contact laws on 6 s at 2 Hz, where the
# pendulum strikes the barrier about twice a drive period (24 contacts in either record).  A
# law shows only through its impacts, so the generator sizes it, and redraws the record,
# until it shows after the baseline's refit: seed 3914's exponent (n = 1.07) on its sixth
# sub-seed, 0.49 noise sigmas left against a threshold of 0.3 (the seed and its first five
# sub-seeds left 0.04-0.29: at 2 Hz the baseline's refit absorbs most of the exponent); seed
# 3915's Kelvin-Voigt damping on the seed itself, 3.3 sigmas
# name: (seed, cause, drive frequency, duration)
SHORT_CASES = {
    "sensor zero, 10 s": (3911, "sensor_offset", 10.0, 10.0),
    "dry friction, 10 s": (3912, "coulomb_friction", 10.0, 10.0),
    "drag, 10 s": (3913, "quadratic_drag", 10.0, 10.0),
    "contact exponent, 2 Hz, 6 s": (3914, "contact_exponent", 2.0, 6.0),
    "contact damping, 2 Hz, 6 s": (3915, "contact_damping_law", 2.0, 6.0),
}
SHORT_MISSES = {
    "drag, 10 s": "known miss: drag (seed 3913) is named none and nothing is flagged, on this "
                  "10 s record and on the seed's 30 s one (not yet diagnosed)",
}


def _short(name: str):
    marks = ([pytest.mark.xfail(strict=True, raises=AssertionError, reason=SHORT_MISSES[name])]
             if name in SHORT_MISSES else [])
    return pytest.param(name, id=name, marks=marks)


@pytest.mark.parametrize("name", [_short(name) for name in SHORT_CASES])
def test_a_cause_is_named_with_its_size_on_a_short_record(name, tmp_path):
    seed, cause, frequency, duration = SHORT_CASES[name]
    case = draw_forced_case(seed, cause, frequency_hz=frequency, duration_s=duration)
    report = analyze_record(load_record(write_forced_case(case, tmp_path)), workers=2).as_json()
    assert [c["cause"] for c in report["causes"]] == [cause], report["ranking"][:3]
    assert report["cause"] == cause
    assert report["unexplained"] is False, report["residual_reading"]["why"]
    found = report["causes"][0]["parameters"]
    for key, truth in case.causes[cause].items():
        assert within_999(found[key], truth), (key, truth, found[key])
    assert report["extended"]["rms_residual"] < 1.5 * case.measurement.angle_noise_rad


def _check_the_command_output(case, report, tmp_path):
    """What ``impact-rig analyze`` says of the drive and the regime, and its page."""
    drive = report["drive"]
    assert drive["stated"] == {"frequency_hz": case.drive.stated_frequency_hz,
                               "amplitude_m": case.drive.stated_amplitude_m}
    offset_ppm = 1e6 * (case.drive.frequency_hz / case.drive.stated_frequency_hz - 1)
    assert drive["frequency_offset_ppm"] == pytest.approx(offset_ppm, abs=10)
    assert drive["frequency_source"] in ("tach", "table")
    assert report["regime"]["label"].startswith(f"period-{case.period}")
    page = (tmp_path / "pages" / "record.md").read_text()
    assert "regime judged from the record" in page and "drive:" in page


# two causes at once: the pair drawn from the seed among every registered cause.  The seeds
# are the range 5301-5302, one record per paper drive frequency, every seed kept.  5302 is a
# 10 Hz record without a laser, a 2 ms sensor lag beside a drive harmonic: the lag fitted
# from its neutral start stayed at 0.3 ms with the viscous damping held at 0 (it was named a
# 1 % table amplitude error, then nothing), and is found from the step's screening solution
PAIR_SEEDS = [
    pytest.param(5301, 2.0, id="2 Hz"),
    pytest.param(5302, 10.0, id="10 Hz"),
]


@pytest.mark.parametrize(("seed", "frequency"), PAIR_SEEDS)
def test_two_causes_at_once_are_both_named_with_their_sizes(seed, frequency, tmp_path):
    pair = draw_pair(seed)
    case = draw_forced_case(seed, pair, frequency_hz=frequency, duration_s=DURATION_S)
    report = analyze_record(load_record(write_forced_case(case, tmp_path)), workers=2).as_json()
    named = {c["cause"]: c for c in report["causes"]}
    assert set(named) == set(pair), (pair, list(named), report["ranking"][:4])
    assert report["cause"] == report["causes"][0]["cause"]
    for cause_name, values in case.causes.items():
        for key, truth in values.items():
            estimate = named[cause_name]["parameters"][key]
            assert within_999(estimate, truth), (cause_name, key, truth, estimate)
    assert report["extended"]["rms_residual"] < 1.5 * case.measurement.angle_noise_rad


# effects outside the registry (reference/unregistered.py): the effect is drawn at a
# size that shows; the analysis must never explain it confidently with a named cause, must
# flag it, and must give the finding of its kind where it leaves one
UNREGISTERED = {
    "sensor zero drift, 2 Hz": (5401, "sensor_zero_drift", 2.0),
    "heavy-tailed noise, 10 Hz": (5402, "heavy_tailed_noise", 10.0),
}


@pytest.mark.parametrize("name", list(UNREGISTERED))
def test_an_effect_outside_the_registry_is_flagged_and_never_explained(name, tmp_path):
    seed, effect, frequency = UNREGISTERED[name]
    case = draw_unregistered_case(seed, effect, frequency_hz=frequency, duration_s=DURATION_S)
    report = analyze_record(load_record(write_forced_case(case, tmp_path)), workers=2).as_json()
    spec = EFFECTS[effect]
    kinds = {f["kind"] for f in report["residual_findings"]}
    named = [c["cause"] for c in report["causes"]]
    if spec.domain == "noise":  # the decoy: the baseline is right, the noise has spikes
        assert named == [] and report["cause"] == "none", report["ranking"][:3]
    else:
        assert not named or report["unexplained"], (named, report["ranking"][:3])
        assert report["unexplained"] or spec.finding in kinds, kinds
    assert spec.finding in kinds, (effect, kinds)
