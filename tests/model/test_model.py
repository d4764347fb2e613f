"""The model's parameters, nondimensional form, contact law and cause registry against
docs/MODEL.md."""

import math

import numpy as np
import pytest

from analysis.extensions import CAUSES, apply_measurement, cause
from analysis.model import (
    PAPER_CASES,
    Drive,
    Model,
    Nondimensional,
    RigParameters,
    acceleration,
    contact_force,
    from_nondimensional,
    paper_case,
    to_nondimensional,
)
from analysis.packed import P, ParameterError

MODEL_MD_CAUSES = {
    "coulomb_friction", "quadratic_drag", "barrier_offset", "contact_exponent",
    "contact_damping_law", "sensor_offset", "sensor_nonlinearity", "sensor_lag",
    "excitation_distortion", "excitation_amplitude",
}


@pytest.mark.parametrize(
    "field, value",
    [("L_m", -0.01), ("m_kg", 0.0), ("l_m", float("nan")), ("R_m", -1.0), ("zeta", -0.1),
     ("E_Pa", 0.0), ("theta_b_rad", 2.0), ("mu0_s_per_m", "fast")],
)
def test_invalid_parameter_names_the_field(field, value):
    with pytest.raises(ParameterError, match=field):
        RigParameters(**{field: value})


def test_drive_with_amplitude_needs_a_frequency():
    with pytest.raises(ParameterError, match="frequency_hz"):
        Drive(amplitude_m=0.001, frequency_hz=0.0)


def test_nondimensional_round_trip():
    rig = RigParameters(L_m=0.052, zeta=0.011, E_Pa=3.1e6, mu0_s_per_m=0.4)
    drive = Drive(amplitude_m=0.004, frequency_hz=7.0)
    back_rig, back_drive = from_nondimensional(to_nondimensional(rig, drive), 7.0, rig)
    for name in ("L_m", "zeta", "E_Pa", "mu0_s_per_m"):
        assert getattr(back_rig, name) == pytest.approx(getattr(rig, name), rel=1e-12)
    assert back_drive.amplitude_m == pytest.approx(drive.amplitude_m, rel=1e-12)


def test_nondimensional_groups_follow_eq_15_with_paper_numbers():
    # docs/MODEL.md section 4: eq. 15c with R = 19 mm (the diameter) gives the paper's gammas.
    rig = RigParameters(R_m=0.019)
    for f_hz, gamma_paper in ((2.0, 1.888e4), (10.0, 755.5)):
        nd = to_nondimensional(rig, Drive(amplitude_m=0.001, frequency_hz=f_hz))
        assert nd.gamma == pytest.approx(gamma_paper, rel=0.01)
    nd10 = to_nondimensional(rig, Drive(amplitude_m=0.001, frequency_hz=10.0))
    assert nd10.eta == pytest.approx(0.232, rel=0.01)
    assert nd10.mu == pytest.approx(2.356, rel=0.01)
    # ... and with the radius, the values docs/MODEL.md quotes.
    assert to_nondimensional(RigParameters(), Drive(0.001, 10.0)).gamma == pytest.approx(
        533.5, rel=0.01
    )


def test_paper_cases_are_named_and_keep_their_groups():
    assert sorted(PAPER_CASES) == list("abcdefghi")
    for name, case in PAPER_CASES.items():
        rig, drive = paper_case(name).dimensional()
        nd = to_nondimensional(rig, drive)
        for group in ("eta", "beta", "mu", "gamma"):
            assert getattr(nd, group) == pytest.approx(getattr(case.nondimensional, group))
    with pytest.raises(ParameterError, match="a, b, c"):
        paper_case("z")


def hertz_hunt_crossley(theta, theta_dot, rig: RigParameters):
    """docs/MODEL.md section 2 written out independently."""
    delta = rig.l_m * (math.sin(theta) - math.sin(rig.theta_b_rad))
    if delta <= 0:
        return 0.0
    delta_dot = rig.l_m * math.cos(theta) * theta_dot
    K = 4.0 / 3.0 * rig.E_Pa * math.sqrt(rig.R_m)
    return max(K * (1 + rig.mu0_s_per_m * delta_dot) * delta**1.5, 0.0)


@pytest.mark.parametrize("theta_b", [0.0, 0.02, -0.03])
def test_contact_force_is_hunt_crossley_on_hertz(theta_b):
    rig = RigParameters(theta_b_rad=theta_b)
    p = Model(rig).pack()
    rng = np.random.default_rng(1)
    for theta, theta_dot in zip(rng.uniform(-0.1, 0.1, 200), rng.uniform(-3, 3, 200), strict=True):
        expected = hertz_hunt_crossley(theta, theta_dot, rig)
        assert contact_force(theta, theta_dot, p) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_contact_only_at_positive_angles_and_never_pulls():
    p = Model().pack()
    assert contact_force(-0.01, -1.0, p) == 0.0
    assert contact_force(0.01, 0.0, p) > 0.0
    # Fast separation: (1 + mu0 deltadot) < 0 would pull; the force is clamped at zero.
    assert contact_force(1e-4, -1000.0, p) == 0.0
    # Beyond the horizontal sin(theta) > sin(theta_b) again, but the barrier is at the bottom.
    assert contact_force(math.pi - 0.1, 0.0, p) == 0.0
    assert contact_force(0.01, 0.0, Model(barrier=False).pack()) == 0.0


def test_equation_of_motion_signs():
    rig = RigParameters()
    drive = Drive(amplitude_m=0.002, frequency_hz=5.0)
    p = Model(rig, drive, barrier=False).pack()
    t, theta, theta_dot = 0.013, -0.2, 0.7
    Omega = drive.Omega_rad_s
    expected = (
        -2 * rig.zeta * rig.omega_rad_s * theta_dot
        + drive.amplitude_m * Omega**2 / rig.L_m * math.sin(Omega * t) * math.cos(theta)
        - rig.omega_rad_s**2 * math.sin(theta)
    )
    assert acceleration(t, theta, theta_dot, p) == pytest.approx(expected, rel=1e-12)


def test_registry_holds_every_named_cause_of_model_md():
    assert set(CAUSES) == MODEL_MD_CAUSES


def test_dynamics_causes_change_only_their_terms():
    rig, drive = paper_case("h").dimensional()
    base = Model(rig, drive).pack()
    changed = {
        "coulomb_friction": ({"Tc_N_m": 1e-4}, {P.COULOMB_ACC}),
        "quadratic_drag": ({"c2_per_rad": 0.3}, {P.C2}),
        "barrier_offset": ({"theta_b_rad": 0.01}, {P.THETA_B, P.SIN_THETA_B}),
        "contact_exponent": ({"n": 1.2, "K_n": 5e4}, {P.EXPONENT, P.K}),
        "contact_damping_law": ({"c_N_s_per_m": 2.0}, {P.MU0, P.C_VISCOUS}),
        "excitation_distortion": ({"h2": 0.1, "phi2_rad": 0.5}, {P.A2, P.PHI2}),
        "excitation_amplitude": ({"eps": 0.05}, {P.A1}),
    }
    for name, (values, slots) in changed.items():
        extended = Model(rig, drive).with_extension(name, **values).pack()
        differs = {P(i) for i in np.flatnonzero(extended != base)}
        assert differs == slots, name
    friction = Model(rig, drive).with_extension("coulomb_friction", Tc_N_m=1e-4).pack()
    assert friction[P.COULOMB_ACC] == pytest.approx(1e-4 / (rig.m_kg * rig.L_m**2))


def test_cause_parameters_are_validated():
    with pytest.raises(ParameterError, match="Tc_N_m"):
        Model().with_extension("coulomb_friction", Tc_N_m=-1.0)
    with pytest.raises(ParameterError, match="unknown parameter"):
        Model().with_extension("sensor_offset", offset=0.1)


def test_measurement_causes_act_on_the_signal_only():
    t = np.arange(0, 2, 1e-3)
    theta = 0.1 * np.sin(2 * np.pi * 2 * t)
    model = Model().with_extension("sensor_offset", offset_rad=0.02)
    np.testing.assert_allclose(apply_measurement(model, t, theta), theta + 0.02)
    model = Model().with_extension("sensor_nonlinearity", k3=0.5)
    np.testing.assert_allclose(apply_measurement(model, t, theta), theta + 0.5 * theta**3)
    # A first-order lag of a sine: gain 1/sqrt(1 + (w tau)^2), checked on the steady state.
    tau = 0.02
    lagged = apply_measurement(Model().with_extension("sensor_lag", tau_s=tau), t, theta)
    w = 2 * np.pi * 2
    steady = lagged[t > 1.0]
    assert steady.max() == pytest.approx(0.1 / math.sqrt(1 + (w * tau) ** 2), rel=2e-3)
    # and its phase: the continuous filter's steady state to the sampling's second order
    # (a filter holding each sample trails by tau - dt/2: 0.6 mrad off here)
    exact = 0.1 / math.hypot(1.0, w * tau) * np.sin(w * t - math.atan(w * tau))
    np.testing.assert_allclose(steady, exact[t > 1.0], rtol=0, atol=1e-5)
    # a ramp, started settled, trails by tau from its first sample, and a stream cut in
    # blocks reads the same as in one piece
    lag = cause("sensor_lag").measurement
    ramp = lag(t, 0.3 * t, {"tau_s": 0.004}, 0.3)
    np.testing.assert_allclose(ramp, 0.3 * (t - 0.004), rtol=0, atol=1e-12)
    carry: dict[str, float] = {}
    blocks = [lag(t[a:a + 700], theta[a:a + 700], {"tau_s": tau}, None, carry)
              for a in range(0, t.size, 700)]
    np.testing.assert_allclose(np.concatenate(blocks), lagged, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(Model().pack(), Model().with_extension(
        "sensor_offset", offset_rad=0.02).pack())


def test_nondimensional_validation():
    with pytest.raises(ParameterError, match="eta"):
        Nondimensional(eta=0.0, beta=0.1, mu=1.0, gamma=10.0)


def test_sensor_causes_compose_along_the_chain_whatever_their_order():
    """A lag, a linearity error and a zero read the angle in the sensor chain's order, so a
    model that added the zero first reads theta + k3 theta^3 + offset, not (theta + c)^3."""
    from analysis.model_values import measured_angle

    t = np.arange(2000) / 1000.0
    theta = 0.3 * np.sin(2 * np.pi * 2.0 * t)
    values = {"k3": 0.7, "offset_rad": 0.02, "tau_s": 0.004}
    expected = theta + 0.7 * theta**3 + 0.02
    for causes in (("sensor_offset", "sensor_nonlinearity"),
                   ("sensor_nonlinearity", "sensor_offset")):
        np.testing.assert_allclose(measured_angle(causes, values, t, theta), expected,
                                   rtol=0, atol=1e-15)
    lagged = measured_angle(("sensor_lag",), values, t, theta, 0.3 * 2 * np.pi * 2.0)
    for causes in (("sensor_offset", "sensor_lag", "sensor_nonlinearity"),
                   ("sensor_nonlinearity", "sensor_offset", "sensor_lag")):
        np.testing.assert_allclose(measured_angle(causes, values, t, theta,
                                                  0.3 * 2 * np.pi * 2.0),
                                   lagged + 0.7 * lagged**3 + 0.02, rtol=0, atol=1e-15)
    # a model's own extensions, added zero first, read the same way
    model = Model().with_extension("sensor_offset", offset_rad=0.02).with_extension(
        "sensor_nonlinearity", k3=0.7)
    np.testing.assert_allclose(apply_measurement(model, t, theta), expected, rtol=0,
                               atol=1e-15)
