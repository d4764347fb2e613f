"""Periodic orbits by shooting and their continuation, against long simulations, a brute-force
bifurcation diagram and the harmonic balance of a weakly forced pendulum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import fsolve

from analysis.dynamics import simulate_bifurcation
from analysis.dynamics.continuation import continue_orbits
from analysis.dynamics.model_parameters import model_with
from analysis.dynamics.period_map import PeriodMap
from analysis.dynamics.periodic_orbits import find_periodic_orbit
from analysis.model import Drive, Model, RigParameters, paper_case
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate, simulate_packed
from tests.dynamics.baseline_reference import reference_image


def _case_g(**values: float) -> Model:
    rig, drive = paper_case("g").dimensional()
    model = Model(rig, drive)
    for name, value in values.items():
        model = model_with(model, name, value)
    return model


@pytest.fixture(scope="module")
def gap_branches():
    """Case (g)'s rig with a 0.02 rad gap to the barrier: the period-1 orbit grazes, then
    period-doubles; its period-2 orbit period-doubles again on the way back down."""
    model = _case_g(theta_b_rad=0.02, beta=0.017)
    # 64 points a branch: the tests read the period-4 branch's start only; the sensitivities
    # follow it through a grazing, folds and period-doublings back to 0.017 (330 points)
    return continue_orbits(PeriodMap(model, "beta"), 0.017, 0.034, np.zeros(2), max_periods=4,
                           max_points=64)


def test_stable_orbit_is_the_attractor_of_a_long_simulation():
    # the paper's case (g): its simulation settles on a period-2 orbit that strikes the barrier
    model = _case_g()
    orbit = find_periodic_orbit(PeriodMap(model, "beta", 2), 0.022, np.array([-0.12, -0.7]))
    assert orbit.stable and orbit.residual < 1e-10
    start = orbit.state + np.array([2e-3, -0.05])
    run = simulate(
        model, *start,
        settings=SimulationSettings(
            duration_s=0.4, fs_hz=100, skip_s=400.0, rtol=1e-10, atol=1e-12,
        ),
    )
    assert run.contacts.count >= 2
    settled = np.column_stack([run.poincare.theta, run.poincare.theta_dot])
    # the run's phase-0 samples alternate between the orbit's state and its image
    partner = PeriodMap(model, "beta", 1).images(0.022, orbit.state)[0]
    for sample in settled:
        distance = min(np.abs(sample - orbit.state).max(), np.abs(sample - partner).max())
        assert distance < 1e-8


def test_multipliers_match_a_fit_to_single_runs():
    # an independent estimate: a least-squares linear map through 16 runs of the single-run
    # simulator (another entry point, tolerance and stencil) on a ring around the orbit
    model = _case_g()
    period_map = PeriodMap(model, "beta", 2)
    orbit = find_periodic_orbit(period_map, 0.022, np.array([-0.12, -0.7]))
    p = model.pack()
    radius = np.array([1e-6, 1e-6 * p[P.OMEGA_DRIVE]])  # theta' scaled by Omega
    angles = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    offsets = np.column_stack([np.cos(angles), np.sin(angles)]) * radius
    images = []
    for offset in offsets:
        start = orbit.state + offset
        run = simulate_packed(
            p, *start,
            settings=SimulationSettings(duration_s=0.2 + 1e-9, fs_hz=10.0, rtol=1e-12, atol=1e-14),
        )
        images.append([run.poincare.theta[2], run.poincare.theta_dot[2]])
    fitted, *_ = np.linalg.lstsq(offsets, np.array(images) - orbit.linearisation.image,
                                 rcond=None)
    fitted_multipliers = np.sort_complex(np.linalg.eigvals(fitted.T))
    assert np.allclose(np.sort_complex(orbit.multipliers), fitted_multipliers, atol=1e-5)
    richardson = period_map.linearise(0.022, orbit.state, richardson=True)
    assert richardson.jacobian_error < 1e-6
    assert np.allclose(richardson.multipliers, orbit.multipliers, atol=1e-6)


def test_free_orbit_jacobian_has_the_flow_s_known_determinant():
    # away from the barrier only viscous damping shrinks areas: det J = exp(-2 zeta omega T)
    model = _case_g(theta_b_rad=0.02, beta=0.01)
    orbit = find_periodic_orbit(PeriodMap(model, "beta"), 0.01, np.zeros(2))
    rig = model.rig
    expected = math.exp(-2.0 * rig.zeta * rig.omega_rad_s / model.drive.frequency_hz)
    assert np.prod(orbit.multipliers).real == pytest.approx(expected, rel=1e-8)


def test_period_doubling_sits_where_the_brute_force_diagram_doubles(gap_branches):
    period_two = [b for b in gap_branches.branches if b.periods == 2]
    assert period_two, "no period-2 branch switched to at the period-1 period-doubling"
    doublings = [e for e in period_two[0].events if e.kind == "period_doubling"]
    assert len(doublings) == 1
    event = doublings[0]
    assert event.bracket[1] - event.bracket[0] < 1e-6
    assert any(b.periods == 4 and b.values[0] == pytest.approx(event.value, abs=1e-4)
               for b in gap_branches.branches)
    # brute force: sweep down from a stable period-2 orbit of the branch above the doubling
    branch = period_two[0]
    j = int(np.argmin(np.abs(branch.values - 0.0333)))
    assert branch.stable[j]
    model = _case_g(theta_b_rad=0.02)
    betas = 0.0306 + 4e-4 * np.arange(7)
    _, down = simulate_bifurcation(model, betas, periods=3000, record_periods=8,
                                   initial_state=tuple(branch.states[j]))
    periods = [_period(samples) for samples in down.theta]
    doubled = [b for b, k in zip(betas, periods, strict=True) if k == 4]
    single = [b for b, k in zip(betas, periods, strict=True) if k == 2]
    assert doubled and single
    assert max(doubled) < event.value < min(single)
    assert min(single) - max(doubled) == pytest.approx(4e-4)


def _period(samples: np.ndarray) -> int:
    """Smallest k with the Poincare samples repeating after k (to 1e-7 rad)."""
    for k in range(1, samples.size):
        if np.all(np.abs(samples[k:] - samples[:-k]) < 1e-7):
            return k
    return 0


def test_grazing_matches_where_a_long_simulation_first_touches(gap_branches):
    period_one = gap_branches.branches[0]
    grazings = [e for e in period_one.events if e.kind == "grazing"]
    assert len(grazings) == 1
    grazing = grazings[0]
    assert grazing.bracket[1] - grazing.bracket[0] < 1e-6
    start = grazing.point.state
    model = _case_g(theta_b_rad=0.02)
    distances = []
    offsets = np.array([-2e-6, 2e-6])
    for offset in offsets:
        run = simulate(
            model_with(model, "beta", grazing.value + offset), *start,
            settings=SimulationSettings(
                duration_s=0.1, fs_hz=1e5, skip_s=300.0, rtol=1e-10, atol=1e-12,
            ),
        )
        distances.append(0.02 - run.theta.max())
    assert distances[0] > 0 > distances[1]
    zero = offsets[0] - distances[0] * (offsets[1] - offsets[0]) / (distances[1] - distances[0])
    assert abs(zero) < 1e-6


def _harmonic_balance_residual(unknowns, phase, rig: RigParameters, beta: float):
    """Fundamental-harmonic balance of theta'' + 2 zeta w theta' + w^2 sin theta
    = beta Omega^2 sin(Omega t) cos theta for theta = a cos(Omega t + phase), every term
    projected on cos and sin by quadrature (exact for the pendulum's nonlinearity)."""
    amplitude, Omega = unknowns
    w = rig.omega_rad_s
    tau = np.linspace(0.0, 2.0 * math.pi, 128, endpoint=False)
    theta = amplitude * np.cos(tau + phase)
    rate = -amplitude * Omega * np.sin(tau + phase)
    accel = -amplitude * Omega**2 * np.cos(tau + phase)
    residual = (accel + 2 * rig.zeta * w * rate + w**2 * np.sin(theta)
                - beta * Omega**2 * np.sin(tau) * np.cos(theta))
    return [np.mean(residual * np.cos(tau)), np.mean(residual * np.sin(tau))]


def test_weakly_forced_pendulum_matches_harmonic_balance_through_its_folds():
    rig = RigParameters(zeta=0.002)
    beta = 0.0016
    model = Model(rig, Drive(amplitude_m=beta * rig.L_m, frequency_hz=2.6), barrier=False)
    result = continue_orbits(PeriodMap(model, "f_drive_hz"), 2.6, 2.0, np.zeros(2))
    (branch,) = result.branches
    folds = [e for e in branch.events if e.kind == "fold"]
    assert len(folds) == 2
    assert not branch.stable.all() and branch.stable.any()
    period_map = PeriodMap(model, "f_drive_hz")
    errors = []
    for point in branch.points:
        orbit = period_map.orbit(point.value, point.state)
        Omega = 2 * math.pi * point.value
        c = 2.0 * np.mean(orbit.theta * np.exp(-1j * Omega * orbit.t))
        amplitude, phase = abs(c), np.angle(c)
        solution = fsolve(_harmonic_balance_residual, [amplitude, Omega],
                          args=(phase, rig, beta), xtol=1e-10)
        errors.append((solution[0] / amplitude - 1.0, solution[1] / Omega - 1.0, point.stable))
    errors = np.array(errors)
    unstable = errors[:, 2] == 0
    assert unstable.sum() >= 3  # the middle branch between the folds is compared too
    assert np.abs(errors[:, 0]).max() < 0.01
    assert np.abs(errors[:, 1]).max() < 1e-3
    # the folds where harmonic balance has them (extremes of its frequency along the phase)
    lags = np.linspace(0.1, math.pi - 0.1, 2000)  # theta lags the drive's sine by this
    guess = [0.04, 0.98 * rig.omega_rad_s]
    curve = []
    for phase in -0.5 * math.pi - lags:
        guess = fsolve(_harmonic_balance_residual, guess, args=(phase, rig, beta), xtol=1e-10)
        curve.append(guess[1] / (2 * math.pi))
    curve = np.array(curve)
    turns = np.flatnonzero(np.diff(np.sign(np.diff(curve))))
    assert len(turns) == 2
    predicted = np.sort(curve[turns + 1])
    located = np.sort([e.value for e in folds])
    assert np.allclose(located, predicted, rtol=2e-4)


def test_branch_points_carry_the_orbit_s_angles_at_drive_phase_zero(gap_branches):
    # a period-2 point's two section angles: its own state and its image after one period
    # (read off the orbit's sampled second pass, another integration than the map's)
    branch = next(b for b in gap_branches.branches if b.periods == 2)
    point = branch.points[len(branch.points) // 2]
    once = PeriodMap(_case_g(theta_b_rad=0.02), "beta", 1).images(point.value, point.state)[0]
    assert point.section_theta.shape == (2,)
    assert point.section_theta[0] == pytest.approx(point.state[0], abs=1e-7)
    assert point.section_theta[1] == pytest.approx(once[0], abs=1e-7)
    assert abs(point.section_theta[1] - point.section_theta[0]) > 1e-3


def test_brute_force_diagram_over_another_parameter_sets_that_parameter():
    model = _case_g()
    dampings = np.array([0.005, 0.02])
    (by_name,) = simulate_bifurcation(model, dampings, periods=40, record_periods=4,
                                      mode="fixed", parameter="zeta")
    assert by_name.parameter_name == "zeta"
    for i, zeta in enumerate(dampings):
        (direct,) = simulate_bifurcation(model_with(model, "zeta", zeta), [0.022],
                                         periods=40, record_periods=4, mode="fixed")
        np.testing.assert_array_equal(by_name.theta[i], direct.theta[0])
    assert not np.allclose(by_name.theta[0], by_name.theta[1])


def test_a_period_doubling_a_hair_past_a_grazing_still_gives_its_period_8_branch():
    """The gallery's 10 Hz rig: the period-4 branch doubles 8.5e-7 in beta past the grazing
    that gives it a new contact, where the map is nearly non-smooth.  The arclength switch
    (parameter free) sends Newton back and forth across the barrier there; from 614c1c0 the
    period-8 branch was not followed at all (issue 34).  The flip is subcritical: the
    period-8 orbit lives below the doubling, unstable, and turns at a fold."""
    model = _case_g(beta=0.01)
    period_s = 1.0 / model.drive.frequency_hz
    run = simulate(model, 0.0, 0.0, settings=SimulationSettings(
        duration_s=period_s, fs_hz=1.0 / period_s, skip_s=2000 * period_s))
    start = np.array([run.poincare.theta[-1], run.poincare.theta_dot[-1]])
    result = continue_orbits(PeriodMap(model, "beta", 2), 0.01, 0.108, start, max_periods=8)
    four = next(b for b in result.branches if b.periods == 4)
    grazings = [e.value for e in four.events if e.kind == "grazing"]
    doubling = next(e for e in four.events if e.kind == "period_doubling")
    assert min(abs(doubling.value - g) for g in grazings) < 1e-5  # the hard case, still
    eight = [b for b in result.branches if b.periods == 8]
    assert len(eight) == 1, four.stop_reason
    branch = eight[0]
    assert branch.values.min() < doubling.value - 1e-5  # below the doubling: subcritical
    fold = next(e for e in branch.events if e.kind == "fold")
    # the fold's orbit, checked with the scipy reference simulator: period 8, not 4
    state = fold.point.state
    at_fold = model_with(model, "beta", fold.value)
    assert np.abs(reference_image(at_fold, state, 8) - state).max() < 1e-6
    assert np.abs(reference_image(at_fold, state, 4) - state).max() > 1e-3
