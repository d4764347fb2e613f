"""Shaker dynamics against analytic ramps and an independent ODE solution."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hardware_sim.shaker_response import ShakerDynamics, ShakerResponse


def test_amplitude_ramps_at_the_ramp_rate_without_lag() -> None:
    response = ShakerResponse(ShakerDynamics(amplitude_tau_s=0.0, frequency_tau_s=0.0))
    response.set_targets(amplitude_m=0.003, frequency_hz=10.0, ramp_rate_m_s=0.002)
    assert response.advance_to(0.5).amplitude_m == pytest.approx(0.001)
    assert response.advance_to(1.0).amplitude_m == pytest.approx(0.002)
    out = response.advance_to(2.0)
    assert out.amplitude_m == pytest.approx(0.003) and not out.ramping
    response.set_targets(amplitude_m=0.0)
    assert response.advance_to(2.5).amplitude_m == pytest.approx(0.002)
    assert response.advance_to(4.0).at_zero


def test_frequency_slews_at_its_limit() -> None:
    response = ShakerResponse(ShakerDynamics(frequency_slew_hz_s=20.0, frequency_tau_s=0.0))
    response.set_targets(frequency_hz=10.0)
    assert response.advance_to(0.25).frequency_hz == pytest.approx(5.0)
    assert response.advance_to(1.0).frequency_hz == pytest.approx(10.0)


def test_lagged_ramp_matches_an_independent_ode_solution() -> None:
    tau, rate, target = 0.05, 0.01, 0.002
    response = ShakerResponse(ShakerDynamics(amplitude_tau_s=tau))
    response.set_targets(amplitude_m=target, ramp_rate_m_s=rate)
    times = np.linspace(0.01, 0.6, 37)
    ours = np.array([response.advance_to(t).amplitude_m for t in times])

    def command(t: float) -> float:
        return min(rate * t, target)

    ode = solve_ivp(
        lambda t, y: [(command(t) - y[0]) / tau],
        (0, 0.6),
        [0.0],
        t_eval=times,
        rtol=1e-10,
        atol=1e-13,
        max_step=1e-3,
    )
    np.testing.assert_allclose(ours, ode.y[0], atol=1e-9)


def test_one_long_step_equals_many_short_ones() -> None:
    coarse, fine = ShakerResponse(), ShakerResponse()
    for r in (coarse, fine):
        r.set_targets(amplitude_m=0.004, frequency_hz=15.0, ramp_rate_m_s=0.003)
    for t in np.linspace(0, 1.7, 1701)[1:]:
        fine.advance_to(float(t))
    a, b = coarse.advance_to(1.7), fine.output()
    assert a.amplitude_m == pytest.approx(b.amplitude_m, rel=1e-9)
    assert a.frequency_hz == pytest.approx(b.frequency_hz, rel=1e-9)
