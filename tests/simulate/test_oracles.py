"""The simulator against analytic oracles: energy, Hertz, restitution, averaging, friction."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import quad

from analysis.model import Drive, Model, RigParameters
from analysis.simulate import SimulationSettings, simulate


def _energy_per_mass(rig: RigParameters, theta_b: float, theta, theta_dot) -> np.ndarray:
    """E / m: kinetic + gravity + contact potential (integral of the model's contact torque)."""
    K, shaft, L = rig.K_N_per_m1_5, rig.l_m, rig.L_m
    sin_b = math.sin(theta_b)

    def contact_torque(th: float) -> float:
        delta = shaft * (math.sin(th) - sin_b)
        return shaft * K * delta**1.5 if delta > 0 else 0.0

    potential = np.array(
        [quad(contact_torque, theta_b, th)[0] if th > theta_b else 0.0 for th in theta]
    )
    return (
        0.5 * L**2 * np.asarray(theta_dot) ** 2
        + rig.g_m_s2 * L * (1.0 - np.cos(theta))
        + potential / rig.m_kg
    )


def test_energy_is_conserved_through_many_impacts_without_damping():
    rig = RigParameters(zeta=0.0, mu0_s_per_m=0.0)
    for theta_b, model in (
        (0.0, Model(rig)),
        (0.08, Model(rig).with_extension("barrier_offset", theta_b_rad=0.08)),
    ):
        result = simulate(
            model, -1.0,
            settings=SimulationSettings(
                duration_s=6.0, fs_hz=400, poincare_phase=None, rtol=1e-10, atol=1e-12,
            ),
        )
        assert result.ok
        assert result.contacts.count >= 20
        # energy at every sample, in contact too (contact potential by quadrature) ...
        energy = _energy_per_mass(rig, theta_b, result.theta, result.theta_dot)
        drift = np.abs(energy / energy[0] - 1.0)
        assert drift.max() < 1e-6
        # ... and at the exact entry and exit states of every contact
        c = result.contacts
        e_in = _energy_per_mass(rig, theta_b, c.theta_in, c.theta_dot_in)
        e_out = _energy_per_mass(rig, theta_b, c.theta_out, c.theta_dot_out)
        assert np.abs(e_out / e_in - 1.0).max() < 1e-7
        assert np.abs(e_in / energy[0] - 1.0).max() < 1e-6


def test_single_impact_matches_hertz_contact_time_and_penetration():
    # zeta = mu0 = 0: the only force in contact besides Hertz is gravity, ~ omega^2 theta with
    # theta < delta_max / l ~ 1e-2, small against the contact force: the oracle's assumption.
    rig = RigParameters(zeta=0.0, mu0_s_per_m=0.0)
    m_eff = rig.m_kg * rig.L_m**2 / rig.l_m**2
    K = rig.K_N_per_m1_5
    for theta0 in (-0.05, -0.15):
        result = simulate(
            Model(rig), theta0,
            settings=SimulationSettings(duration_s=0.6, fs_hz=10, rtol=1e-11, atol=1e-13),
        )
        c = result.contacts
        assert c.count >= 1
        v = rig.l_m * c.theta_dot_in[0]
        delta_max = (5.0 * m_eff * v**2 / (4.0 * K)) ** 0.4
        t_contact = 3.2181 * (m_eff**2 / (K**2 * v)) ** 0.2
        assert abs(c.delta_max_m[0] / delta_max - 1.0) < 0.01
        assert abs(c.duration_s[0] / t_contact - 1.0) < 0.01
        assert abs(c.theta_dot_out[0] / c.theta_dot_in[0] + 1.0) < 1e-6  # elastic


def test_restitution_approaches_one_minus_two_thirds_mu0_v():
    ratios = []
    for mu0 in (0.4, 0.2, 0.1):
        rig = RigParameters(zeta=0.0, mu0_s_per_m=mu0)
        c = simulate(
            Model(rig), -0.1,
            settings=SimulationSettings(duration_s=0.6, fs_hz=10, rtol=1e-11, atol=1e-13),
        ).contacts
        v = rig.l_m * c.theta_dot_in[0]
        restitution = -c.theta_dot_out[0] / c.theta_dot_in[0]
        ratios.append((1.0 - restitution) / (2.0 / 3.0 * mu0 * v))
    errors = np.abs(np.array(ratios) - 1.0)
    assert errors[-1] < 0.01  # mu0 v ~ 0.007
    assert errors[0] > errors[1] > errors[2]  # the approximation improves as mu0 v -> 0


def test_free_decay_follows_the_averaging_solution():
    rig = RigParameters()
    omega, zeta, theta0 = rig.omega_rad_s, rig.zeta, 0.1
    result = simulate(
        Model(rig, barrier=False), theta0, -zeta * omega * theta0,
        settings=SimulationSettings(duration_s=10.0, fs_hz=500),
    )
    t = result.t
    averaged = (
        theta0
        * np.exp(-zeta * omega * t)
        * np.cos(omega * t + theta0**2 / (32 * zeta) * (np.exp(-2 * zeta * omega * t) - 1))
    )
    rms = np.sqrt(np.mean((result.theta - averaged) ** 2))
    assert rms < 1e-3 * theta0
    assert result.contacts.count == 0


def test_coulomb_friction_decay_and_final_stick():
    rig = RigParameters(zeta=0.0)
    omega2 = rig.g_m_s2 / rig.L_m
    friction_acc = 0.1  # Tc / (m L^2) [1/s^2]
    model = Model(rig, barrier=False).with_extension(
        "coulomb_friction", Tc_N_m=friction_acc * rig.m_kg * rig.L_m**2
    )
    result = simulate(
        model, 0.02,
        settings=SimulationSettings(duration_s=8.0, fs_hz=100, dense=True, poincare_phase=None),
    )
    d = result.dense
    at_rest = np.flatnonzero(d.theta_dot == 0.0)
    turning = d.theta[at_rest]
    turning = turning[np.concatenate(([True], np.diff(turning) != 0.0))]  # drop the stuck run
    amplitude = np.abs(turning)
    # exact energy balance over each half swing: omega^2 (cos a2 - cos a1) = Tc_acc (a1 + a2)
    lhs = omega2 * (np.cos(amplitude[1:]) - np.cos(amplitude[:-1]))
    rhs = friction_acc * (amplitude[1:] + amplitude[:-1])
    assert np.abs(lhs / rhs - 1.0).max() < 1e-6
    # small amplitude: the amplitude falls by 2 Tc_acc / omega^2 per half swing (4 per period)
    assert np.allclose(-np.diff(amplitude), 2 * friction_acc / omega2, rtol=2e-3)
    # it ends stuck where gravity cannot overcome friction, and stays exactly there
    final = turning[-1]
    assert omega2 * abs(math.sin(final)) <= friction_acc
    assert omega2 * abs(math.sin(turning[-2])) > friction_acc
    stuck_from = d.t[np.flatnonzero(d.theta == final)[0]]
    later = result.t > stuck_from
    assert later.sum() > 100
    assert np.all(result.theta[later] == final)
    assert np.all(result.theta_dot[later] == 0.0)


def test_stuck_pendulum_releases_when_the_table_acceleration_exceeds_friction():
    rig = RigParameters(zeta=0.0)
    drive = Drive(amplitude_m=0.001, frequency_hz=5.0)
    table_acc = drive.amplitude_m * drive.Omega_rad_s**2 / rig.L_m  # peak, in 1/s^2
    for friction_acc, releases in ((0.5 * table_acc, True), (1.05 * table_acc, False)):
        model = Model(rig, drive, barrier=False).with_extension(
            "coulomb_friction", Tc_N_m=friction_acc * rig.m_kg * rig.L_m**2
        )
        result = simulate(model, 0.0, 0.0, settings=SimulationSettings(duration_s=0.5, fs_hz=1000))
        if releases:
            # at rest at theta = 0 only the table acts: release when A Omega^2/L |sin| = Tc_acc
            expected = math.asin(friction_acc / table_acc) / drive.Omega_rad_s
            assert result.sticks.count >= 1
            assert abs(result.sticks.t_end[0] - expected) < 1e-12
            assert np.abs(result.theta).max() > 1e-4
        else:
            assert result.sticks.count == 0
            assert np.all(result.theta == 0.0)
