"""Multiple shooting on a chaotic record: a segment whose state sits on a motion the record
does not show takes its predecessor's continued motion instead.

The record comes from the independent reference simulator (``reference``); the fit
starts from the true parameters and the true states, one segment's state thrown far off.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identify import shooting
from analysis.identify.forced import (
    BASELINE_PLANS,
    ForcedModel,
    forced_data,
    free_parameters,
    record_segments,
)
from analysis.record_loaders import load_record
from reference.forced_records import draw_forced_case, write_forced_case

THROWN = 17  # the segment thrown off


@pytest.fixture(scope="module")
def chaotic_case(tmp_path_factory):
    """A chaotic 10 Hz record of the reference simulator, and its data as the fit sees it."""
    case = draw_forced_case(7101, "none", frequency_hz=10.0, regime="chaotic", laser=True,
                            duration_s=8.0)
    record = load_record(write_forced_case(case, tmp_path_factory.mktemp("chaotic")))
    return case, forced_data(record).for_regime("chaotic")


@pytest.fixture(scope="module")
def thrown_off(chaotic_case):
    """The problem, the true states and the states with one thrown off."""
    case, data = chaotic_case
    segments = record_segments(data)
    rig = case.rig
    truth = {"omega_rad_s": rig.omega_rad_s, "zeta": rig.zeta,
             "K_N_per_m1.5": rig.K_N_per_m1_5, "mu0_s_per_m": rig.mu0_s_per_m}
    free = free_parameters(list(BASELINE_PLANS), truth)
    problem = ForcedModel(data, ()).problem(segments, free, {}, threads=2)
    motion = case.motion
    at = segments.start  # the record's samples are the motion's, both from 0
    true_states = np.column_stack([motion.theta_rad[at], motion.theta_dot_rad_s[at]])
    states = true_states.copy()
    states[THROWN, 1] = -states[THROWN, 1] + 3.0 * np.sign(states[THROWN, 1] or 1.0)
    return problem, true_states, states, data.noise_rad


def test_a_thrown_off_segment_takes_its_predecessors_motion(thrown_off, monkeypatch):
    problem, true_states, states, noise = thrown_off
    fit = problem.fit(states, max_iterations=2)
    assert abs(fit.states[THROWN, 0] - true_states[THROWN, 0]) < 3 * noise
    assert abs(fit.states[THROWN, 1] - true_states[THROWN, 1]) < 0.05
    assert fit.rms < 1.2 * noise
    # without the repair the same fit leaves it where it was thrown
    monkeypatch.setattr(shooting.ShootingProblem, "_continued_states",
                        lambda self, values, states, motion: None)
    stuck = problem.fit(states, max_iterations=2)
    assert abs(stuck.states[THROWN, 1] - true_states[THROWN, 1]) > 0.5
    assert stuck.rms > 1.2 * noise


def test_runs_split_over_threads_equal_one_whole_run_to_the_bit(thrown_off):
    """A trial step's run shares its segments out to the threads; segments are independent,
    so the angles and end states must be exactly those of one run over all of them."""
    problem, true_states, _states, _noise = thrown_off
    assert len(problem.times.groups) == 2  # two threads: two runs of segments
    values = problem.values_of(np.zeros(len(problem.free)))
    split = problem.run(values, true_states, split=True)
    whole = problem.run(values, true_states, split=False)
    for a, b in zip(split, whole, strict=True):
        np.testing.assert_array_equal(a, b)
    # and the groups cover every segment once, in order
    edges = [g for pair in problem.times.groups for g in pair]
    assert edges[0] == 0 and edges[-1] == problem.segments.count
    assert all(edges[i] == edges[i + 1] for i in range(1, len(edges) - 1, 2))


@pytest.mark.parametrize("sensor, size", [("sensor_nonlinearity", {"k3": -0.3}),
                                          ("sensor_offset", {"offset_rad": 0.02})])
def test_a_sensor_without_memory_reads_every_sample_at_once_to_the_same_bit(
        thrown_off, chaotic_case, sensor, size):
    """A zero or a cubic reads each sample alone: one call over all segments' samples gives
    what the call per chain of segments gives (a filter could not: it is read per chain)."""
    from analysis.model_values import measurement_has_memory

    problem, true_states, _states, _noise = thrown_off
    assert not measurement_has_memory((sensor,)) and measurement_has_memory(("sensor_lag",))
    model = ForcedModel(chaotic_case[1], (sensor,))
    sensed = model.problem(problem.segments, problem.free, size, threads=2)
    assert not sensed.measure_has_memory
    values = sensed.values_of(np.zeros(len(sensed.free)))
    at_once, _ = sensed.run(values, true_states)
    sensed.measure_has_memory = True
    per_chain, _ = sensed.run(values, true_states)
    np.testing.assert_array_equal(at_once, per_chain)
    plain, _ = problem.run(values, true_states)
    assert np.max(np.abs(at_once - plain)) > 1e-4  # the sensor does act


def test_a_column_that_moves_only_the_sensor_is_read_from_the_motion_to_the_bit(
        thrown_off, chaotic_case, monkeypatch):
    """The Jacobian's column of a sensor's own parameter re-reads the current motion instead
    of running the model again: the same numbers as the run, and one run fewer."""
    problem, true_states, _states, _noise = thrown_off
    model = ForcedModel(chaotic_case[1], ("sensor_nonlinearity",))
    free = [*problem.free, shooting.FreeParameter("k3", -0.3, 1e-3, False, -10.0, 10.0)]
    sensed = model.problem(problem.segments, free, {}, threads=2)
    u = np.zeros(len(sensed.free))
    values = sensed.values_of(u)
    motion = sensed._integrate(values, true_states, True)
    theta, ends = sensed.read(values, *motion)
    r = sensed.residuals(theta, ends, true_states)
    hs = np.array([1e-6, 1e-6])
    runs = []
    integrate = sensed._integrate
    monkeypatch.setattr(sensed, "_integrate", lambda *a: runs.append(1) or integrate(*a))
    reread = sensed._jacobian(u, true_states, r, theta, ends, hs, motion)
    with_motion = len(runs)
    rerun = sensed._jacobian(u, true_states, r, theta, ends, hs)
    assert len(runs) - with_motion == with_motion + 1  # k3's column ran only without it
    np.testing.assert_array_equal(reread.toarray(), rerun.toarray())
    assert np.any(reread.toarray()[:, len(free) - 1] != 0.0)  # the column is k3's own


def test_states_fitted_alone_run_to_the_horizon_and_combine_readings_to_the_bit(
        thrown_off, chaotic_case, monkeypatch):
    """Fitting each segment's state alone, with no sensor memory linking segments, runs each
    segment only as far as the samples it fits so far reach, and takes an improved segment's
    reading from its trial run: the same states as running every sample again each time."""
    problem, _true_states, states, _noise = thrown_off
    model = ForcedModel(chaotic_case[1], ("sensor_offset",))
    sensed = model.problem(problem.segments, problem.free, {"offset_rad": 0.0}, threads=2)
    times_run = []
    integrate = shooting.integrate_segments
    monkeypatch.setattr(shooting, "integrate_segments",
                        lambda p, t0, s0, out_t, *a, **k:
                        times_run.append(out_t.size) or integrate(p, t0, s0, out_t, *a, **k))
    combined = sensed.fit_states(states, iterations=3)
    short_runs = sum(times_run)
    sensed.measure_has_memory = True  # per chain: the same readings, run again each time
    times_run.clear()
    rerun = sensed.fit_states(states, iterations=3)
    np.testing.assert_array_equal(combined, rerun)
    assert np.max(np.abs(combined - states)) > 0.0  # the fit moved the states
    assert short_runs < 0.75 * sum(times_run)  # a quarter, then half, then all of each


def test_fits_side_by_side_give_the_numbers_each_gives_alone(thrown_off, chaotic_case):
    """Independent fits run at once, a thread each, end where each ends alone on two
    threads: the results do not depend on how the cores were shared out."""
    from analysis.discrepancy.forced_models import SideBySide

    problem, true_states, states, _noise = thrown_off

    def fit(start: np.ndarray, threads: int | None) -> shooting.ShootingFit:
        model = ForcedModel(chaotic_case[1], ())
        return model.problem(problem.segments, problem.free, {}, threads=threads).fit(
            start, max_iterations=2)

    alone = {"thrown": fit(states, 2), "true": fit(true_states, 2)}
    with SideBySide(threads=2) as batch:
        pending = {"thrown": batch.add(fit, states), "true": batch.add(fit, true_states)}
    together = {key: fit.result for key, fit in pending.items()}
    for key, single in alone.items():
        assert together[key].values == single.values
        np.testing.assert_array_equal(together[key].states, single.states)
    assert together["thrown"].rss != together["true"].rss  # two different fits


def test_the_normal_equations_summed_by_structure_are_those_of_the_jacobian(
        thrown_off, chaotic_case):
    """The fit's J^T J and J^T r, summed segment by segment and link by link, equal the
    products of the whole Jacobian (also with the rows weighted, as the robust intervals
    weight them)."""
    problem, _true_states, states, _noise = thrown_off
    u = np.zeros(len(problem.free))
    values = problem.values_of(u)
    motion = problem._integrate(values, states, True)
    theta, ends = problem.read(values, *motion)
    r = problem.residuals(theta, ends, states)
    jac = problem._jacobian(u, states, r, theta, ends, np.array([1e-6, 1e-6]), motion)
    dense = jac.toarray()
    assert problem.links.size > 0 and np.count_nonzero(jac.link_state) > 0
    scale = np.abs(np.sin(np.arange(r.size))) + 0.1
    for weights in (None, scale):
        weighted = dense if weights is None else dense * weights[:, None]
        expected = weighted.T @ weighted
        np.testing.assert_allclose(jac.normal_matrix(weights).toarray(), expected, rtol=1e-9,
                                   atol=1e-9 * np.abs(expected).max())
    expected = dense.T @ r
    np.testing.assert_allclose(jac.gradient(r), expected, rtol=1e-9,
                               atol=1e-9 * np.abs(expected).max())
