"""The paper's numerical observations at its nondimensional parameters (docs/MODEL.md section 4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from analysis.model import Model, acceleration, paper_case
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate

INITIAL_STATES = [(-0.2, 0.0), (-0.8, 3.0), (0.0, -6.0), (-1.2, 0.0)]


def _model(case: str) -> Model:
    rig, drive = paper_case(case).dimensional()
    return Model(rig, drive)


def _poincare(case: str, theta0: float, theta_dot0: float, transient: int, kept: int):
    model = _model(case)
    period = 1.0 / model.drive.frequency_hz
    result = simulate(
        model, theta0, theta_dot0,
        settings=SimulationSettings(
            duration_s=(kept - 0.5) * period, fs_hz=model.drive.frequency_hz,
            skip_s=transient * period,
        ),
    )
    assert result.ok, result.status
    assert result.poincare.theta.size == kept
    return np.column_stack((result.poincare.theta, result.poincare.theta_dot))


def _smallest_period(samples: np.ndarray, tolerance: float, max_period: int = 16) -> int | None:
    """Smallest k <= max_period with x[n + k] == x[n] (to ``tolerance``) over all samples."""
    scale = np.abs(samples).max(axis=0)
    for k in range(1, max_period + 1):
        if np.all(np.abs(samples[k:] - samples[:-k]) <= tolerance * scale):
            return k
    return None


@pytest.mark.parametrize("case", ["a", "c"])
def test_cases_a_and_c_are_periodic(case):
    for theta0, theta_dot0 in INITIAL_STATES[:2]:
        samples = _poincare(case, theta0, theta_dot0, transient=150, kept=32)
        assert _smallest_period(samples, 1e-6) is not None


def test_case_d_has_a_period_two_attractor():
    periods = {
        _smallest_period(_poincare("d", th, om, transient=300, kept=32), 1e-6)
        for th, om in INITIAL_STATES
    }
    assert 2 in periods


def test_case_g_settles_on_a_periodic_orbit_not_chaos():
    for theta0, theta_dot0 in INITIAL_STATES:
        samples = _poincare("g", theta0, theta_dot0, transient=800, kept=32)
        assert _smallest_period(samples, 1e-6) is not None


def test_case_i_settles_on_no_periodic_orbit():
    for theta0, theta_dot0 in INITIAL_STATES:
        samples = _poincare("i", theta0, theta_dot0, transient=500, kept=64)
        assert _smallest_period(samples, 1e-3) is None


@pytest.mark.xfail(
    strict=True,
    reason="at the paper's quoted beta = 0.114 the model of docs/MODEL.md (and the paper's own "
    "small-angle eq. 14, integrated independently) sits in a period-3 window; chaos appears "
    "at beta = 0.118-0.120 (case i). See test_case_h_agrees_with_an_independent_integrator.",
)
def test_case_h_settles_on_no_periodic_orbit():
    for theta0, theta_dot0 in INITIAL_STATES:
        samples = _poincare("h", theta0, theta_dot0, transient=500, kept=64)
        assert _smallest_period(samples, 1e-3) is None


def test_case_h_agrees_with_an_independent_integrator():
    """scipy's DOP853 with terminal events, restarted at each contact, same equations."""
    model = _model("h")
    p = model.pack()
    p_free = p.copy()
    p_free[P.BARRIER] = 0.0
    period = 1.0 / model.drive.frequency_hz
    n = 25
    times = np.arange(n) * period
    reference = np.full(n, np.nan)
    t, y, contact = 0.0, np.array([-0.2, 0.0]), False

    def surface(t, y):
        return y[0] - p[P.THETA_B]

    while t < times[-1]:
        pr = p if contact else p_free
        surface.terminal = True
        surface.direction = -1.0 if contact else 1.0
        sol = solve_ivp(
            lambda t, y, pr=pr: [y[1], acceleration(t, y[0], y[1], pr)],
            (t, times[-1]),
            y,
            method="DOP853",
            rtol=1e-11,
            atol=1e-13,
            events=surface,
            dense_output=True,
        )
        inside = (times >= t) & (times <= sol.t[-1])
        if inside.any() and sol.t.size > 1:
            reference[inside] = sol.sol(times[inside])[0]
        if sol.status != 1:
            break
        t, y, contact = sol.t_events[0][0], sol.y_events[0][0], not contact
    ours = simulate(
        model, -0.2, 0.0,
        settings=SimulationSettings(
            duration_s=times[-1] + 0.5 * period, fs_hz=10, rtol=1e-11, atol=1e-13,
        ),
    )
    assert np.abs(ours.poincare.theta[:n] - reference).max() < 1e-6
    # and the attractor it reaches is the period-3 orbit, not a fixed point or chaos
    samples = _poincare("h", -0.2, 0.0, transient=300, kept=32)
    assert _smallest_period(samples, 1e-6) == 3
