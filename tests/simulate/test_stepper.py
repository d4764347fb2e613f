"""The streaming Stepper: chunked advancing, parameter changes with continuous phase, releases."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from analysis.model import Drive, Model, RigParameters, paper_case
from analysis.packed import P
from analysis.simulate import (
    SimulationSettings,
    SimulationStoppedError,
    Stepper,
    simulate,
    simulate_ensemble,
    simulate_packed,
)


def _case_h() -> Model:
    rig, drive = paper_case("h").dimensional()
    return Model(rig, drive)


def test_many_chunks_equal_one_run():
    model = _case_h()
    fs = 20000.0
    whole = simulate(
        model, -0.3, 0.5,
        settings=SimulationSettings(duration_s=2.0, fs_hz=fs, poincare_phase=None),
    )
    stepper = Stepper(model, -0.3, 0.5)
    rng = np.random.default_rng(7)
    edges = np.unique(np.concatenate(([0], rng.integers(1, whole.t.size, 300), [whole.t.size])))
    theta = np.concatenate([stepper.advance(whole.t[a:b])[0] for a, b in pairwise(edges)])
    assert theta.size == whole.t.size
    assert np.abs(theta - whole.theta).max() < 1e-9
    assert stepper.t == whole.t[-1]
    contacts = stepper.pop_contacts()
    assert contacts.count == np.count_nonzero(whole.contacts.t_out <= whole.t[-1])
    assert np.allclose(contacts.t_in, whole.contacts.t_in[: contacts.count], rtol=0, atol=1e-12)
    assert stepper.pop_contacts().count == 0


def test_set_model_changes_the_drive_with_continuous_phase():
    rig = RigParameters()
    first = Model(rig, Drive(amplitude_m=0.003, frequency_hz=8.0))
    second = Model(rig, Drive(amplitude_m=0.005, frequency_hz=10.0))
    stepper = Stepper(first, -0.2, rtol=1e-11, atol=1e-13)
    t_switch = 1.2345
    stepper.advance(np.linspace(0.01, t_switch, 100))
    phase_before = stepper.drive_phase
    state = (stepper.theta, stepper.theta_dot)
    stepper.set_model(second)
    assert math.isclose(stepper.drive_phase, phase_before, abs_tol=1e-9)
    assert (stepper.theta, stepper.theta_dot) == state
    later = t_switch + np.arange(1, 3001) / 2000.0
    theta, _ = stepper.advance(later)
    # reference: the second model started from the switch state, drive phase carried over
    p = second.pack()
    p[P.PHASE0] = phase_before
    reference = simulate_packed(
        p, *state,
        settings=SimulationSettings(duration_s=1.5005, fs_hz=2000.0, rtol=1e-11, atol=1e-13),
    )
    assert np.abs(theta - reference.theta[1:]).max() < 1e-7
    # a discontinuous phase (restart at phase 0) would give a clearly different motion
    p[P.PHASE0] = 0.0
    jumped = simulate_packed(
        p, *state,
        settings=SimulationSettings(duration_s=1.5005, fs_hz=2000.0),
    )
    assert np.abs(theta - jumped.theta[1:]).max() > 1e-3


def test_set_state_releases_the_pendulum_from_a_new_angle():
    model = Model(RigParameters(), barrier=False)
    stepper = Stepper(model, 0.0)
    stepper.advance(np.array([0.5]))
    assert stepper.theta == 0.0
    stepper.set_state(0.2, 0.0)
    times = 0.5 + np.arange(1, 2001) / 1000.0
    theta, theta_dot = stepper.advance(times)
    reference = simulate(
        model, 0.2, 0.0,
        settings=SimulationSettings(duration_s=2.001, fs_hz=1000.0),
    )
    assert np.abs(theta - reference.theta[1:2001]).max() < 1e-8
    assert np.abs(theta_dot - reference.theta_dot[1:2001]).max() < 1e-7


def test_going_over_the_top_stops_with_a_clear_error_and_bad_times_are_refused():
    rig = RigParameters(zeta=0.0)
    stepper = Stepper(Model(rig), 0.0, -2.2 * rig.omega_rad_s)
    with pytest.raises(ValueError, match="non-decreasing"):
        stepper.advance(np.array([0.2, 0.1]))
    with pytest.raises(SimulationStoppedError, match="over_the_top"):
        stepper.advance(np.linspace(0.001, 2.0, 2000))
    assert stepper.status == "over_the_top"
    stepper.set_state(0.1, 0.0)
    assert stepper.status == "ok"
    theta, _ = stepper.advance(stepper.t + np.array([0.01, 0.02]))
    assert np.all(np.isfinite(theta))


@pytest.mark.parametrize(
    ("settings", "named"),
    [
        ({"rtol": 0.0}, "rtol"),
        ({"rtol": math.nan}, "rtol"),
        ({"rtol": 1e-16}, "rtol"),
        ({"atol": -1e-11}, "atol"),
        ({"max_step_s": 0.0}, "max_step_s"),
        ({"max_step_s": math.nan}, "max_step_s"),
    ],
)
def test_every_entry_point_refuses_step_settings_it_cannot_honour(settings, named):
    model = Model()
    runs = (
        lambda: Stepper(model, -0.2, **settings),
        lambda: simulate(model, -0.2, settings=SimulationSettings(duration_s=0.1, **settings)),
        lambda: simulate_ensemble(model.pack(), np.array([-0.2, 0.0]), 0.1, **settings),
    )
    for run in runs:
        with pytest.raises(ValueError, match=named):
            run()


def test_a_pendulum_at_rest_keeps_time_for_hours():
    # resting on the barrier, undriven: the error estimate is exactly zero, so without a
    # cap the step grows tenfold per step to infinity and no later sample is ever written
    model = Model(rig=RigParameters(), drive=Drive(), barrier=True)
    stepper = Stepper(model, 0.0, 0.0)
    for hour in (1, 2):
        times = 3600.0 * hour + np.arange(10.0)
        theta, _ = stepper.advance(times)
        assert np.all(theta == 0.0), theta
        assert stepper.t < 3600.0 * hour + 10.0 + 1.0  # no step reached far beyond
    # and when the drive starts, it moves within its first period
    stepper.set_model(Model(rig=RigParameters(), drive=Drive(0.005, 10.0), barrier=True))
    theta, _ = stepper.advance(7210.0 + np.arange(1, 11) / 100.0)
    assert np.ptp(theta) > 1e-3
