"""The paper's forced cases (docs/MODEL.md section 4) judged from simulations of our model.

Each run: 200 drive periods of transient, then 300 periods recorded with sensor noise
added, judged as a measured record is.  The expected kinds are what the paper's own
simulations report; the Lyapunov exponent of the tangent dynamics is an independent
check of the periodic/chaotic verdict.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from analysis.dynamics import (
    Regime,
    SpectrumSettings,
    fnn_dimension,
    judge_record_regime,
    model_lyapunov_spectrum,
    mutual_information_delay,
    rosenstein_lyapunov,
)
from analysis.model import Model, paper_case
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate
from reference.simulator import Pendulum, TableMotion, simulate_reference

TRANSIENT_PERIODS = 200
RECORD_PERIODS = 300
NOISE_RAD = 5e-4


def _run(name: str, theta0: float = 0.0, theta_dot0: float = 0.0):
    return _run_once(name, float(theta0), float(theta_dot0))


def _classify(name: str, theta0: float = 0.0, theta_dot0: float = 0.0) -> Regime:
    return _classify_once(name, float(theta0), float(theta_dot0))


# a case's run and its verdict, deterministic functions of the case and the start, serve the
# test of its kind and the test of the verdict against the exponent: each computed once
@functools.cache
def _run_once(name: str, theta0: float, theta_dot0: float):
    rig, drive = paper_case(name).dimensional()
    model = Model(rig, drive)
    period = drive.period_s
    result = simulate(
        model, theta0, theta_dot0,
        settings=SimulationSettings(
            duration_s=RECORD_PERIODS * period, fs_hz=40 * drive.frequency_hz,
            skip_s=TRANSIENT_PERIODS * period, rtol=1e-8, atol=1e-10,
        ),
    )
    assert result.ok, result.status
    return model, result


@functools.cache
def _classify_once(name: str, theta0: float, theta_dot0: float) -> Regime:
    model, result = _run_once(name, theta0, theta_dot0)
    return _judge(model, result)


def _judge(model, result) -> Regime:
    """The regime of the run read as a record: noisy angle, strobed at the stated drive
    (the run starts at drive phase 0: a whole number of periods was skipped)."""
    noisy = result.theta + NOISE_RAD * np.random.default_rng(0).normal(size=result.theta.size)
    regime, _ = judge_record_regime(
        noisy, result.fs_hz, NOISE_RAD, frequency_hz=model.drive.frequency_hz
    )
    return regime


@pytest.mark.parametrize("name", ["a", "c"])
def test_low_frequency_cases_are_periodic_with_superharmonics(name):
    regime = _classify(name)
    assert regime.kind == "periodic"
    assert regime.period == 1
    assert len(regime.evidence["superharmonics"]) >= 2


def test_case_d_has_a_period_two_attractor():
    initial_conditions = [(0.0, 0.0), (-0.1, 0.0), (0.05, -1.0)]
    found = [_classify("d", *ic) for ic in initial_conditions]
    assert all(regime.kind == "periodic" for regime in found)
    assert any(regime.period == 2 for regime in found)
    period_two = next(regime for regime in found if regime.period == 2)
    assert "1/2 f" in period_two.evidence["subharmonics"]


def test_case_g_is_periodic_after_period_doubling():
    regime = _classify("g")
    assert regime.kind == "periodic"
    assert regime.period in (2, 4, 8)


def test_case_i_is_chaotic():
    regime = _classify("i")
    assert regime.kind == "chaotic"
    assert regime.evidence["K"] > 0.8


@pytest.mark.xfail(
    strict=True,
    reason="paper's simulation: chaotic; in this model beta = 0.114 falls in a period-3 window "
    "(chaos at beta = 0.112 and 0.118, negative Lyapunov exponent at 0.114)",
)
def test_case_h_is_chaotic_as_in_the_paper():
    assert _classify("h").kind == "chaotic"


@pytest.mark.parametrize("name", ["d", "g", "h", "i"])
def test_verdict_agrees_with_the_sign_of_the_lyapunov_exponent(name):
    model, result = _run(name)
    regime = _classify(name)
    period = model.drive.period_s
    per_period = model_lyapunov_spectrum(
        model.pack(),
        result.poincare.theta[0],
        result.poincare.theta_dot[0],
        SpectrumSettings(duration_s=RECORD_PERIODS * period),
        t0_s=result.poincare.t[0],
    ).exponents_per_period[0]
    if regime.kind == "chaotic":
        assert per_period > 0.05
    else:
        assert per_period < -0.01


# The RK4 tangent estimate this project used before the spectrum (fixed steps, 100 per
# contact, tangent by central differences of the acceleration), from the same start
# (the state after 100 periods of ``model_lyapunov_spectrum`` from rest) over the same
# 1000 periods: 0.3106 per period.
RK4_PER_PERIOD = 0.3106


def test_case_i_largest_exponent_against_the_record_and_the_old_estimate():
    """Three estimates of case (i)'s largest exponent.  The spectrum's own resolution is the
    spread of its per-period growth over 1000 periods (batch means: about 0.02 per period,
    7 %); a different trajectory of the same attractor (RK4's) must agree within three of
    those; Rosenstein's method on the angle record of the independent reference simulator
    (its delay and dimension chosen from the record) carries a bias of its own besides (the
    fit of a straight stretch): agreement within 20 %."""
    rig, drive = paper_case("i").dimensional()
    model = Model(rig, drive)
    p = model.pack()
    period = drive.period_s
    spectrum = model_lyapunov_spectrum(
        p, 0.0, 0.0, SpectrumSettings(duration_s=1000 * period, transient_s=100 * period)
    )
    largest = spectrum.exponents_per_period[0]
    growth = np.diff(spectrum.running[:, 0] * spectrum.time, prepend=0.0)  # per period
    batches = growth.reshape(20, -1).mean(axis=1)
    spread = float(np.std(batches, ddof=1) / np.sqrt(batches.size))
    assert largest > 0.1 and spread < 0.1 * largest
    assert spectrum.exponents_per_period[1] < -largest  # areas shrink: contact damping
    assert abs(largest - RK4_PER_PERIOD) < 3.0 * spread

    pendulum = Pendulum(m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta, K_n=p[P.K],
                        mu0_s_per_m=p[P.MU0])
    table = TableMotion(amplitude_m=drive.amplitude_m, frequency_hz=drive.frequency_hz)
    fs_hz = 20 * drive.frequency_hz
    # from the spectrum's first measured state, on the attractor (no transient to run again)
    t = spectrum.t[0] + np.arange(300 * 20) / fs_hz
    theta = simulate_reference(pendulum, table, *spectrum.states[0], t, t_start_s=spectrum.t[0],
                               rtol=1e-9, atol=1e-11).theta_rad
    delay = mutual_information_delay(theta, max_lag=60).delay
    dimension = fnn_dimension(theta, delay, max_dimension=7).dimension
    from_data = rosenstein_lyapunov(theta, fs_hz, dimension=dimension, delay=delay).exponent
    assert from_data * period == pytest.approx(largest, rel=0.2)
