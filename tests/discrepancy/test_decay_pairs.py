"""Two causes at once in a free or an impact decay: both named, each with its size, and
nothing else; one cause alone gains no companion.

The decays are drawn by the reference simulator (``reference/free_decays.py`` and
``reference/decays.py``: scipy DOP853, not the project's integrator) with the causes
at seeded sizes; the analysis sees one CSV and its JSON sidecar.
"""

from __future__ import annotations

import pytest

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.decays import PAIRS as DECAY_PAIRS
from reference.decays import draw_pair_decay
from reference.free_decays import draw_free_decay
from tests.tolerance import Z_95, Z_999

CASES = {
    "friction + sensor cubic": (8901, ("coulomb_friction", "sensor_nonlinearity")),
    "friction + sensor zero": (8902, ("coulomb_friction", "sensor_offset")),
    "sensor cubic + sensor zero": (8903, ("sensor_nonlinearity", "sensor_offset")),
    "friction alone": (8904, ("coulomb_friction",)),
}


def _named_with_their_sizes(decay, causes: tuple[str, ...], tmp_path) -> None:
    """The decay's analysis names exactly ``causes``, leaves nothing unexplained, and holds
    each true size within its 99.9 % interval."""
    report = analyze_record(load_record(decay.write(tmp_path)), workers=2).as_json()
    named = {entry["cause"]: entry for entry in report["causes"]}
    assert set(named) == set(causes), [(c["cause"], c["verdict"]) for c in report["causes"]]
    assert report["cause"] == report["causes"][0]["cause"]
    assert not report["unexplained"], report["residual_reading"]["why"]
    for cause, values in decay.causes.items():
        for parameter, truth in values.items():
            estimate = named[cause]["parameters"][parameter]
            low, high = estimate["ci95"]
            half = (high - low) / 2.0 * Z_999 / Z_95
            assert abs(estimate["value"] - truth) <= half, (cause, parameter, truth, estimate)


@pytest.mark.parametrize("name", list(CASES))
def test_each_cause_of_a_decay_is_named_with_its_size(name, tmp_path):
    seed, causes = CASES[name]
    _named_with_their_sizes(draw_free_decay(seed, causes), causes, tmp_path)


# Free and impact decays with two causes from reference/decays.py (the decay benchmark's
# generator): each seed is the benchmark's draw of that pair (7000 + 47 i).
REFERENCE_PAIRS = {
    # a sensor cubic beside drag gained 1040 in the information criterion but was not added:
    # its effect shows in the early, large swings, and the prediction of the record's tail
    # judged it against the noise's own scatter instead of by a paired test
    "free: drag + sensor cubic": (7141, 3),
    "impact: barrier offset + Kelvin-Voigt contact": (7376, 8),
    "impact: contact exponent + dry friction": (7517, 11),
}


@pytest.mark.parametrize("name", list(REFERENCE_PAIRS))
def test_both_causes_of_a_reference_decay_are_named_with_their_sizes(name, tmp_path):
    seed, index = REFERENCE_PAIRS[name]
    pair = DECAY_PAIRS[index]
    _named_with_their_sizes(draw_pair_decay(seed, pair), pair.causes, tmp_path)
