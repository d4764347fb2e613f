"""The screening of the causes on a forced record: a cause whose cold start ended in a worse
basin than the baseline's is screened again from the baseline's solution.

The record comes from the independent reference simulator (``reference``); dry
friction hides in it, and its screening is started from a friction torque 36 times the
true one, as a cold start far off can be.
"""

from __future__ import annotations

from analysis.discrepancy.forced import rescreened_from_baseline
from analysis.discrepancy.forced_models import cause_hints, screen_cause
from analysis.extensions import BASELINE, NONE, ModelSpec
from analysis.identify.forced import forced_data, identify_forced
from analysis.record_loaders import load_record
from reference.forced_records import draw_forced_case, write_forced_case
from tests.tolerance import resolves


def test_a_screening_stuck_worse_than_the_baseline_starts_again_from_it(tmp_path):
    case = draw_forced_case(9137, "coulomb_friction", frequency_hz=10.0, laser=False,
                            duration_s=10.0)
    data = forced_data(load_record(write_forced_case(case, tmp_path)))
    ident = identify_forced(data, whole=False, threads=2)
    hints = cause_hints(ident)
    base = screen_cause(data, BASELINE, ident, hints, 2)
    stuck = screen_cause(data, ModelSpec.of("coulomb_friction"), ident,
                         {**hints, "Tc_N_m": 1e-2}, 2)
    assert stuck.rss > base.rss  # a model holding the baseline, stuck below it
    again = rescreened_from_baseline(data, ident, {NONE: base, "coulomb_friction": stuck}, 2)
    found = again["coulomb_friction"]
    assert found.rss < base.rss
    # the true torque inside the screening's 99.9 % interval, which tells it from none
    truth = case.causes["coulomb_friction"]["Tc_N_m"]
    assert resolves(found.estimates["Tc_N_m"], truth), (found.estimates["Tc_N_m"], truth)
    # a screening that ends closer than the baseline is left as it was
    assert rescreened_from_baseline(data, ident, {NONE: base, "coulomb_friction": found},
                                    2) == {}
