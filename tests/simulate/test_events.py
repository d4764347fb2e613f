"""Contact events land exactly on the surface, steps never straddle it, grazing is caught."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.model import Model, RigParameters, paper_case
from analysis.simulate import SimulationSettings, Stepper, simulate


def _case_h(theta_b: float) -> Model:
    rig, drive = paper_case("h").dimensional()
    model = Model(rig, drive)
    return model.with_extension("barrier_offset", theta_b_rad=theta_b) if theta_b else model


@pytest.mark.parametrize("theta_b", [0.0, 0.05, -0.04])
def test_contact_events_lie_on_the_surface_and_steps_never_cross_it(theta_b):
    result = simulate(
        _case_h(theta_b), -0.2,
        settings=SimulationSettings(duration_s=4.0, fs_hz=20000, skip_s=1.0),
    )
    c = result.contacts
    assert result.ok and c.count > 20
    assert np.abs(c.theta_in - theta_b).max() < 1e-12
    assert np.abs(c.theta_out - theta_b).max() < 1e-12
    assert np.all(c.theta_dot_in > 0) and np.all(c.theta_dot_out < 0)
    assert np.all(c.t_out > c.t_in) and np.all(c.t_in[1:] > c.t_out[:-1])
    # Samples come from the steps' dense output: inside a contact interval every sample is
    # beyond the surface and outside every one is before it, so no step mixed the two.
    in_contact = np.zeros(result.t.size, dtype=bool)
    for t_in, t_out in zip(c.t_in, c.t_out, strict=True):
        in_contact |= (result.t > t_in) & (result.t < t_out)
    assert in_contact.sum() > 100
    assert np.all(result.theta[in_contact] > theta_b - 1e-10)
    assert np.all(result.theta[~in_contact] < theta_b + 1e-10)


def test_grazing_contact_inside_one_step_is_found_and_acts():
    # Undamped, from rest at -0.3 rad, the free swing peaks at +0.3 rad: the barrier sits 1e-7 rad
    # lower, so the contact lasts ~1e-4 s, far shorter than the ~3e-3 s steps the default
    # tolerance takes there.
    # A stiff (steel-like) barrier makes the force dominate gravity even at nanometre depth.
    excess = 1e-7
    theta_b = 0.3 - excess
    rig = RigParameters(zeta=0.0, mu0_s_per_m=0.0, E_Pa=2e12)
    model = Model(rig).with_extension("barrier_offset", theta_b_rad=theta_b)
    loose = simulate(model, -0.3, settings=SimulationSettings(duration_s=0.5, fs_hz=1000))
    assert loose.n_steps < 300
    assert loose.contacts.count == 1
    assert loose.contacts.grazing[0]  # the step ended in free flight: a sign test missed it
    assert abs(loose.contacts.theta_in[0] - theta_b) < 1e-12
    assert abs(loose.contacts.theta_out[0] - theta_b) < 1e-12
    # independent resolution: steps of 1e-5 s, many inside the contact, sign test suffices
    fine = simulate(
        model, -0.3,
        settings=SimulationSettings(
            duration_s=0.5, fs_hz=1000, rtol=1e-12, atol=1e-14, max_step_s=1e-5,
        ),
    )
    assert fine.contacts.count == 1 and not fine.contacts.grazing[0]
    assert abs(loose.contacts.duration_s[0] / fine.contacts.duration_s[0] - 1) < 0.01
    assert np.abs(loose.theta - fine.theta).max() < 1e-6
    # the force acts: the contact is much shorter than the free excursion above theta_b,
    # 2 sqrt(2 excess / (omega^2 sin theta_b)), and the motion afterwards is changed by it
    free_excursion = 2.0 * math.sqrt(2.0 * excess / (rig.g_m_s2 / rig.L_m * math.sin(theta_b)))
    assert fine.contacts.duration_s[0] < 0.8 * free_excursion
    unimpeded = simulate(
        Model(rig, barrier=False), -0.3,
        settings=SimulationSettings(duration_s=0.5, fs_hz=1000),
    )
    after = loose.t > loose.contacts.t_out[0] + 0.05
    assert np.abs(loose.theta[after] - unimpeded.theta[after]).max() > 50 * 1e-6


def test_over_the_top_is_reported_not_turned_into_contact():
    rig = RigParameters(zeta=0.0)
    # enough speed at the bottom to pass the top going away from the barrier
    omega = rig.omega_rad_s
    result = simulate(
        Model(rig), 0.0, -2.2 * omega,
        settings=SimulationSettings(duration_s=2.0, fs_hz=1000),
    )
    assert result.status == "over_the_top"
    assert result.contacts.count == 0
    assert result.t.size < 2000
    assert np.all(np.abs(result.theta) <= math.pi + 0.1)


@pytest.mark.parametrize("t0", [0.0, 1e7])
@pytest.mark.parametrize("depth", [1e-15, 1e-9])
def test_a_start_just_inside_the_barrier_leaving_it_exits_cleanly(depth, t0):
    # Leaving contact, the step is sized from the estimated time to the surface; at a
    # femto-radian depth that estimate is below the smallest step the clock resolves (all
    # the more at t = 1e7 s, where that step is 1e-7 s).  A stiff barrier shortens it further.
    model = Model(RigParameters(E_Pa=2e8))
    theta_b = model.rig.theta_b_rad
    stepper = Stepper(model, theta_b + depth, -1.0, t0=t0)
    stepper.advance(t0 + np.arange(1, 501) * 1e-3)  # raises if the run stops
    first = stepper.pop_contacts()
    assert first.count >= 1
    assert first.t_out[0] - t0 < 1e-6  # the contact it started in ends at once
    assert abs(first.theta_out[0] - theta_b) < 1e-12
    assert abs(first.theta_dot_out[0] + 1.0) < 1e-6


def test_a_slow_near_grazing_entry_is_as_accurate_as_a_tight_run():
    # Undamped, so the speed that just reaches the barrier from theta = 0 is known from the
    # energy; 1e-7 above it the pendulum enters at ~5e-4 of that speed, and the contact it
    # then makes depends on the entry state to a fraction of that.
    theta_b = 0.1
    rig = RigParameters(zeta=0.0, theta_b_rad=theta_b)
    critical = math.sqrt(2.0 * rig.g_m_s2 / rig.L_m * (1.0 - math.cos(theta_b)))
    model = Model(rig)
    runs = [
        simulate(
            model, 0.0, critical * (1 + 1e-7),
            settings=SimulationSettings(duration_s=0.3, fs_hz=1000, **tolerances),
        )
        for tolerances in ({}, {"rtol": 1e-13, "atol": 1e-15})
    ]
    default, tight = (run.contacts for run in runs)
    assert default.count == tight.count == 1
    assert default.theta_dot_in[0] < 1e-3 * critical
    assert abs(default.theta_dot_in[0] / tight.theta_dot_in[0] - 1) < 1e-4
    assert abs(default.delta_max_m[0] / tight.delta_max_m[0] - 1) < 1e-3
    assert abs(default.duration_s[0] / tight.duration_s[0] - 1) < 1e-3
