"""Bifurcation diagrams: simulated sweeps vs the linear steady state, recorded sweeps, plots."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dynamics import (
    PoincareSection,
    bifurcation_from_recording,
    plot_bifurcation,
    simulate_bifurcation,
)
from analysis.model import Drive, Model, RigParameters

DRIVE_HZ = 10.0


def _linear_model() -> Model:
    # no barrier, well damped, small angles: a linear forced oscillator with a known steady state
    rig = RigParameters(zeta=0.05)
    return Model(rig, Drive(amplitude_m=0.001 * rig.L_m, frequency_hz=DRIVE_HZ), barrier=False)


def _steady_state_theta_at_phase_zero(model: Model, beta: float) -> float:
    """theta'' + 2 zeta w theta' + w^2 theta = beta Omega^2 sin(Omega t): theta(2 pi k / Omega)."""
    w, Omega, zeta = model.rig.omega_rad_s, model.drive.Omega_rad_s, model.rig.zeta
    amplitude = beta * Omega**2 / math.hypot(w**2 - Omega**2, 2 * zeta * w * Omega)
    lag = math.atan2(2 * zeta * w * Omega, w**2 - Omega**2)
    return amplitude * math.sin(-lag)


@pytest.mark.parametrize("mode", ["continuation", "fixed"])
def test_linear_sweep_follows_the_analytic_steady_state(mode):
    model = _linear_model()
    betas = np.linspace(0.001, 0.004, 8)
    diagrams = simulate_bifurcation(model, betas, periods=300, record_periods=20, mode=mode)
    assert [d.direction for d in diagrams] == (
        ["up", "down"] if mode == "continuation" else ["fixed"]
    )
    expected = np.array([_steady_state_theta_at_phase_zero(model, b) for b in betas])
    for diagram in diagrams:
        assert np.array_equal(diagram.parameter, betas)
        assert diagram.theta.shape == (8, 20)
        # one point per beta (period 1), at the linear oscillator's value
        assert np.allclose(diagram.theta, expected[:, None], rtol=2e-3, atol=1e-7)


def test_sweep_runs_on_one_thread_and_sorts_betas():
    model = _linear_model()
    (up, down) = simulate_bifurcation(
        model, [0.003, 0.001, 0.002], periods=300, record_periods=5, workers=1
    )
    assert np.array_equal(up.parameter, [0.001, 0.002, 0.003])
    expected = [_steady_state_theta_at_phase_zero(model, b) for b in up.parameter]
    assert np.allclose(down.theta[:, -1], expected, rtol=2e-3)


def test_recorded_sweep_keeps_the_settled_samples_of_each_step():
    sections = [
        PoincareSection(np.arange(5.0), np.zeros(5), np.arange(5.0)),
        np.array([7.0, 8.0]),
    ]
    diagram = bifurcation_from_recording([0.02, 0.03], sections, last=3)
    assert diagram.direction == "recorded"
    assert np.array_equal(diagram.theta[0], [2.0, 3.0, 4.0])
    assert np.array_equal(diagram.theta[1, :2], [7.0, 8.0])
    x, y = diagram.scatter()
    assert np.array_equal(x, [0.02, 0.02, 0.02, 0.03, 0.03])
    assert np.array_equal(y, [2.0, 3.0, 4.0, 7.0, 8.0])
    with pytest.raises(ValueError, match="one section per sweep step"):
        bifurcation_from_recording([0.02], sections)
    with pytest.raises(ValueError, match="last = 0"):  # theta[-0:] would keep every sample
        bifurcation_from_recording([0.02, 0.03], sections, last=0)


def test_plot_draws_every_diagram_and_writes_a_png(tmp_path):
    simulated = simulate_bifurcation(
        _linear_model(), np.linspace(0.001, 0.004, 4), periods=50, record_periods=5, workers=1
    )
    recorded = bifurcation_from_recording([0.002, 0.003], [np.array([-1e-4]), np.array([-2e-4])])
    path = tmp_path / "bifurcation.png"
    figure = plot_bifurcation(*simulated, recorded, title="linear", path=path)
    axes = figure.axes[0]
    assert len(axes.collections) == 3
    assert [t.get_text() for t in axes.get_legend().get_texts()] == [
        "simulation, sweep up",
        "simulation, sweep down",
        "measured",
    ]
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
