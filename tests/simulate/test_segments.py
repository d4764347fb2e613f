"""Many short runs in one call (the segments of a multiple-shooting fit) agree with one long
run started from the same states, and refuse a layout that makes no sense."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.model import Model, paper_case
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate_packed
from analysis.simulate.integrator import STATUS_NAMES
from analysis.simulate.segments import integrate_segments


def _chaotic_run():
    rig, drive = paper_case("h").dimensional()
    p = Model(rig, drive).pack()
    p[P.PHASE0] = 0.4
    run = simulate_packed(
        p, -0.05, 0.0,
        settings=SimulationSettings(
            duration_s=12.0, fs_hz=1000.0, skip_s=5.0, rtol=1e-11, atol=1e-13, poincare_phase=None,
        ),
    )
    return p, run


def test_segments_follow_the_long_run_from_its_states():
    p, run = _chaotic_run()
    starts = np.arange(0, 11000, 250)  # quarter-second segments, contacts in most
    pieces, bounds = [], [0]
    for a in starts:
        pieces.append(run.t[a:a + 251])  # the last time is the next segment's start
        bounds.append(bounds[-1] + 251)
    out_t = np.concatenate(pieces)
    states = np.column_stack([run.theta[starts], run.theta_dot[starts]])
    theta, theta_dot, status = integrate_segments(p, run.t[starts], states, out_t,
                                                  np.array(bounds), rtol=1e-10, atol=1e-12)
    assert {STATUS_NAMES[int(s)] for s in status} == {"ok"}
    reference = np.concatenate([run.theta[a:a + 251] for a in starts])
    # over a quarter second of chaos, both runs agree to their tolerances
    assert np.max(np.abs(theta - reference)) < 1e-7
    rate = np.concatenate([run.theta_dot[a:a + 251] for a in starts])
    assert np.max(np.abs(theta_dot - rate)) < 1e-5


def test_a_segment_with_an_absurd_contact_stops_fast_instead_of_crawling():
    p, run = _chaotic_run()
    stiff = p.copy()
    stiff[P.K] *= 1e12  # a trial a fit might try: the contact takes ever smaller steps
    out_t = run.t[:300]
    theta, _, status = integrate_segments(stiff, run.t[:1], np.array([[0.01, 2.0]]), out_t,
                                          np.array([0, 300]), max_steps=2000)
    assert STATUS_NAMES[int(status[0])] in ("max_steps", "step_size_underflow")
    assert np.isnan(theta[-1])


@pytest.mark.parametrize("bounds", [[0, 5, 5, 10], [1, 10], [0, 9]])
def test_a_layout_that_does_not_cover_the_times_is_refused(bounds):
    p, run = _chaotic_run()
    n = len(bounds) - 1
    with pytest.raises(ValueError, match="bounds"):
        integrate_segments(p, run.t[:n], np.zeros((n, 2)), run.t[:10], np.array(bounds))
