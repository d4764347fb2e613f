"""Largest Lyapunov exponents against published values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dynamics import (
    flow_lyapunov,
    fnn_dimension,
    map_lyapunov,
    model_lyapunov,
    mutual_information_delay,
    rosenstein_lyapunov,
)
from analysis.dynamics.lyapunov import scaling_region
from analysis.model import Drive, Model, RigParameters
from tests.dynamics.reference_systems import (
    HENON_CLASSIC,
    LOGISTIC_FULLY_CHAOTIC,
    LORENZ_CLASSIC,
    henon_jacobian,
    henon_map,
    logistic_jacobian,
    logistic_map,
    lorenz_jacobian,
    lorenz_rhs,
)

from .conftest import LORENZ_DT

# Published largest exponents (Sprott, "Chaos and Time-Series Analysis", table of exponents).
LORENZ_LAMBDA = 0.9056
HENON_LAMBDA = 0.41922


def test_henon_map_exponent_matches_published_value():
    estimate = map_lyapunov(
        henon_map, henon_jacobian, [0.1, 0.1], HENON_CLASSIC, iterations=200_000
    )
    assert estimate.exponent == pytest.approx(HENON_LAMBDA, abs=0.005)


def test_logistic_map_at_r4_has_exponent_ln2():
    estimate = map_lyapunov(
        logistic_map, logistic_jacobian, [0.3], LOGISTIC_FULLY_CHAOTIC, iterations=1_000_000
    )
    assert estimate.exponent == pytest.approx(math.log(2.0), abs=0.005)


def test_logistic_map_in_a_periodic_window_has_negative_exponent():
    # r = 3.2: stable period-2 orbit, multiplier r^2 (1-2x1)(1-2x2) = 0.16 -> lambda = ln(0.16)/2
    estimate = map_lyapunov(
        logistic_map, logistic_jacobian, [0.3], np.array([3.2]), iterations=5_000
    )
    assert estimate.exponent == pytest.approx(0.5 * math.log(0.16), abs=1e-3)


def test_lorenz_exponent_from_variational_equations():
    estimate = flow_lyapunov(
        lorenz_rhs,
        lorenz_jacobian,
        [1.0, 1.0, 1.0],
        LORENZ_CLASSIC,
        dt=0.01,
        duration=2000.0,
        transient=20.0,
    )
    assert estimate.exponent == pytest.approx(LORENZ_LAMBDA, abs=0.03)
    # the running estimate has settled: its last fifth stays near the final value
    assert np.ptp(estimate.curve[-100:]) < 0.05


def test_lorenz_exponent_from_data_by_rosenstein(lorenz_x):
    delay = mutual_information_delay(lorenz_x, max_lag=100).delay
    dimension = fnn_dimension(lorenz_x, delay, max_dimension=6).dimension
    estimate = rosenstein_lyapunov(lorenz_x, 1.0 / LORENZ_DT, dimension=dimension, delay=delay)
    assert estimate.exponent == pytest.approx(LORENZ_LAMBDA, rel=0.15)
    low, high = estimate.fit_range
    assert 0 <= low < high


@pytest.mark.parametrize("noise", [0.0, 1e-3])
def test_periodic_signal_has_no_divergence_to_fit(noise):
    rng = np.random.default_rng(5)
    t = np.arange(4000) * 0.01
    x = np.sin(2 * np.pi * 0.7 * t) + noise * rng.normal(size=t.size)
    with pytest.raises(ValueError, match="no exponential divergence"):
        rosenstein_lyapunov(x, 100.0, dimension=2, delay=36)


def test_scaling_region_finds_the_straight_part():
    steps = np.arange(200)
    curve = np.minimum(-8.0 + 0.05 * steps, 0.0) + 0.5 * np.exp(-steps / 3.0)
    start, stop = scaling_region(curve)
    slope = np.polyfit(steps[start:stop], curve[start:stop], 1)[0]
    assert slope == pytest.approx(0.05, rel=0.02)


def test_undamped_small_pendulum_without_barrier_is_neutral():
    # linear conservative oscillator: a tangent vector turns on an ellipse with axes 1 and omega
    # (theta vs theta' units), so its log growth over T stays within ln(omega) / T of zero
    rig = RigParameters(zeta=0.0)
    model = Model(rig, Drive(), barrier=False)
    duration_s = 60.0
    estimate = model_lyapunov(model.pack(), 0.01, 0.0, duration_s=duration_s)
    assert abs(estimate.exponent) <= np.log(rig.omega_rad_s) / duration_s


def test_damped_free_pendulum_exponent_is_minus_zeta_omega():
    # linear damped oscillator: both exponents are -zeta omega
    rig = RigParameters(zeta=0.05)
    model = Model(rig, Drive(), barrier=False)
    duration_s = 200.0
    estimate = model_lyapunov(model.pack(), 0.01, 0.0, duration_s=duration_s)
    # exact up to the phase wobble of the tangent vector, ln(omega) / T (see above)
    bound = np.log(rig.omega_rad_s) / duration_s
    assert abs(estimate.exponent + rig.zeta * rig.omega_rad_s) <= bound
