"""Lyapunov exponents against published values, and the model's spectrum against its own flow's
divergence (the reference simulator) and against Floquet multipliers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dynamics import (
    SpectrumSettings,
    flow_lyapunov,
    fnn_dimension,
    map_lyapunov,
    model_lyapunov_spectrum,
    mutual_information_delay,
    rosenstein_lyapunov,
)
from analysis.dynamics.lyapunov import scaling_region
from analysis.dynamics.period_map import MAP_ATOL, MAP_RTOL, PeriodMap
from analysis.dynamics.periodic_orbits import find_periodic_orbit
from analysis.model import Drive, Model, RigParameters, paper_case
from analysis.packed import P
from reference.simulator import Pendulum, TableMotion, simulate_reference
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


@pytest.mark.slow
def test_undamped_small_pendulum_without_barrier_is_neutral():
    # a linear conservative oscillator turns a frame in (theta, theta' / omega) rigidly: both
    # exponents vanish up to the small swing's nonlinearity and the integrator's error
    rig = RigParameters(zeta=0.0)
    model = Model(rig, Drive(), barrier=False)
    spectrum = model_lyapunov_spectrum(model.pack(), 0.01, 0.0, SpectrumSettings(duration_s=60.0))
    assert np.all(np.abs(spectrum.exponents_per_s) <= 1e-4)


def test_damped_free_pendulum_exponents_are_minus_zeta_omega():
    # linear damped oscillator: both exponents are -zeta omega; their sum is exact (the
    # divergence), each only up to the phase wobble of the frame, ln(omega) / T; the swing
    # stays far above the integrator's atol (its steps are chosen for the state alone)
    rig = RigParameters(zeta=0.005)
    model = Model(rig, Drive(), barrier=False)
    duration_s = 60.0
    spectrum = model_lyapunov_spectrum(
        model.pack(), 0.01, 0.0, SpectrumSettings(duration_s=duration_s)
    )
    rate = rig.zeta * rig.omega_rad_s
    assert np.sum(spectrum.exponents_per_s) == pytest.approx(-2.0 * rate, rel=1e-6)
    bound = np.log(rig.omega_rad_s) / duration_s
    assert np.all(np.abs(spectrum.exponents_per_s + rate) <= bound)
    assert spectrum.period_s == pytest.approx(2.0 * np.pi / rig.omega_rad_s)
    assert spectrum.running.shape == (spectrum.time.size, 2)


def _contact_divergence_integral(pendulum: Pendulum, table: TableMotion, start: np.ndarray,
                                 t0: float, t1: float) -> float:
    """The integral over [t0, t1] of the contact's share of the divergence of (theta',
    theta''), -d(l Fc / (m L^2)) / d theta' = -(l / (m L^2)) K mu0 delta^(3/2) l cos(theta)
    (docs/MODEL.md section 2), along the reference simulator's run from ``start``:
    Gauss-Legendre in each stretch of contact (the events split the run there)."""
    first = simulate_reference(pendulum, table, *start, np.array([t1]), t_start_s=t0)
    edges = [t0] if start[0] > pendulum.theta_b_rad else []
    for event in first.events:
        if event.kind in ("contact_entry", "contact_exit", "clamp", "unclamp"):
            edges.append(event.t_s)
    if len(edges) % 2:
        edges.append(t1)
    nodes, weights = np.polynomial.legendre.leggauss(48)
    times, scales = [], []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        times.append(0.5 * (a + b) + 0.5 * (b - a) * nodes)
        scales.append(0.5 * (b - a) * weights)
    if not times:
        return 0.0
    t, w = np.concatenate(times), np.concatenate(scales)
    order = np.argsort(t)
    run = simulate_reference(pendulum, table, *start, t[order], t_start_s=t0, t_end_s=t1)
    theta = np.empty(t.size)
    theta[order] = run.theta_rad
    delta = np.maximum(pendulum.l_m * (np.sin(theta) - math.sin(pendulum.theta_b_rad)), 0.0)
    gain = pendulum.l_m / (pendulum.m_kg * pendulum.L_m**2)
    rate = gain * pendulum.K_n * pendulum.mu0_s_per_m * delta**1.5 * pendulum.l_m * np.cos(theta)
    return -float(np.sum(w * rate))


def test_sum_of_the_exponents_is_the_mean_divergence_on_a_chaotic_run():
    """Liouville: the exponents' sum times the time is the integral of the divergence,
    -2 zeta omega in flight plus the contact's damping term, here integrated independently
    along the same trajectory (the reference simulator restarted at each interval's start)."""
    rig, drive = paper_case("i").dimensional()
    model = Model(rig, drive)
    p = model.pack()
    periods = 30
    spectrum = model_lyapunov_spectrum(
        p, 0.0, 0.0, SpectrumSettings(duration_s=periods * drive.period_s,
                                      transient_s=100 * drive.period_s),
    )
    pendulum = Pendulum(m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta, K_n=p[P.K],
                        mu0_s_per_m=p[P.MU0])
    table = TableMotion(amplitude_m=drive.amplitude_m, frequency_hz=drive.frequency_hz)
    contact = sum(
        _contact_divergence_integral(pendulum, table, spectrum.states[k], spectrum.t[k],
                                     spectrum.t[k + 1])
        for k in range(periods)
    )
    duration = spectrum.t[-1] - spectrum.t[0]
    flight = -2.0 * rig.zeta * rig.omega_rad_s * duration
    assert contact < 5.0 * flight  # the contacts dominate: the check sees them
    # measured: 6e-9 (the reference's tolerance and 48 Gauss points per contact)
    assert np.sum(spectrum.exponents_per_s) * duration == pytest.approx(flight + contact,
                                                                         rel=1e-7)


@pytest.mark.parametrize("intervals_per_period", [1, 4])
def test_stable_periodic_orbit_exponents_are_its_floquet_exponents(intervals_per_period):
    """The paper's case (c) settles on a period-1 orbit with real multipliers: once the frame
    has turned to the orbit's eigenvectors, each period's R is their moduli (also as the
    product of shorter intervals' R), so the exponents per period are ln of the continuation
    code's multipliers (finite differences of the map: another route)."""
    rig, drive = paper_case("c").dimensional()
    model = Model(rig, drive)
    beta = drive.amplitude_m / rig.L_m
    period_map = PeriodMap(model, "beta", 1)
    orbit = find_periodic_orbit(period_map, beta, np.zeros(2))
    multipliers = period_map.linearise(beta, orbit.state, richardson=True).multipliers
    assert np.all(multipliers.imag == 0.0)
    spectrum = model_lyapunov_spectrum(
        model.pack(), *orbit.state,
        SpectrumSettings(duration_s=10 * drive.period_s, transient_s=30 * drive.period_s,
                         interval_s=drive.period_s / intervals_per_period,
                         rtol=MAP_RTOL, atol=MAP_ATOL),
    )
    assert np.all(spectrum.exponents_per_s < 0.0)
    expected = np.log(np.abs(multipliers.real))
    assert np.all(np.abs(spectrum.exponents_per_period - expected) < 1e-6)
    # the run stays on the orbit: its stroboscopic states are the orbit's state
    strobe = spectrum.states[::intervals_per_period]
    assert np.max(np.abs(strobe - orbit.state)) < 1e-7


@pytest.mark.parametrize(
    ("values", "named"),
    [
        (dict(duration_s=0.0), "duration_s"),
        (dict(duration_s=1.0, transient_s=-1.0), "transient_s"),
        (dict(duration_s=1.0, interval_s=2.0), "interval_s"),
        (dict(duration_s=1.0, rtol=-1.0), "rtol"),
    ],
)
def test_spectrum_settings_refuse_what_they_cannot_honour(values, named):
    with pytest.raises(ValueError, match=named):
        SpectrumSettings(**values)
