"""The diagram comparison on sweeps from the independent reference simulator, where the
truth is known: the true model agrees step by step, a wrong barrier or drive does not,
and regime changes are placed between the right steps."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analysis.maps import MapRunner
from analysis.model import Drive
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate_packed
from analysis.sweep.diagram import (
    compare_diagram,
    compare_diagrams,
    judge_measured,
    model_orbits,
    regime_changes,
    simulate_sweep,
)
from analysis.sweep.figure import draw_diagrams
from analysis.sweep.steps import DOWN, UP, Sweep
from reference.sweeps import GeneratedSweep, draw_sweep, truth_model

# 4.0, 4.5, 5.0, 4.5, 4.0 Hz at beta 0.1: period 1 throughout, settled within 6 s
# (the reference simulator costs about 0.4 s a simulated second: 50 s here)
SETTINGS = {"parameter": "frequency", "span": (4.0, 5.0), "fixed": 0.1, "up_steps": 3,
            "settle_s": 6.0, "dwell_s": 4.0}


@pytest.fixture(scope="module")
def clean() -> GeneratedSweep:
    return draw_sweep(5, "none", **SETTINGS)


@pytest.fixture(scope="module")
def measured(clean):
    return judge_measured(clean.sweep)


def _start(generated: GeneratedSweep) -> tuple[float, float]:
    return generated.truth.theta0_rad, generated.truth.theta_dot0_rad_s


def test_true_model_agrees_on_every_step(clean, measured):
    comparison = compare_diagram("true", truth_model(clean.truth), clean.sweep, measured,
                                 start=_start(clean))
    assert [s.measured for s in comparison.steps] == ["period-1"] * 5
    assert comparison.agreeing == 5
    assert all(step.distance < 3.0 for step in comparison.steps)  # one orbit through the noise
    assert comparison.summary() == "true: 5 of 5 steps agree"


@pytest.mark.parametrize("cause, values", [("barrier_offset", {"theta_b_rad": 0.02}),
                                           ("excitation_amplitude", {"eps": 0.15})])
def test_a_wrong_barrier_or_drive_is_far_from_the_measured_clouds(clean, measured, cause,
                                                                  values):
    wrong = truth_model(clean.truth).with_extension(cause, **values)
    comparison = compare_diagram("wrong", wrong, clean.sweep, measured, start=_start(clean))
    assert all(step.distance > 10.0 for step in comparison.steps)


def test_state_and_phase_carry_over_as_one_run(clean):
    """Two steps at one setting simulate as one uninterrupted run does."""
    first, second = clean.sweep.steps[:2]
    same = replace(second, frequency_hz=first.frequency_hz, amplitude_m=first.amplitude_m)
    sweep = Sweep("two alike", "frequency", (first, same))
    model = truth_model(clean.truth)
    steps = simulate_sweep(model, sweep, start=(0.05, 0.0), start_phase_rad=0.3)
    fs = first.record.sample_rate_hz
    p = replace(model, drive=Drive(first.amplitude_m, first.frequency_hz)).pack()
    p[P.PHASE0] = 0.3
    total = round((first.settle_s + second.settle_s) * fs) + first.record.time_s.size \
        + second.record.time_s.size
    whole = simulate_packed(p, 0.05, 0.0, settings=SimulationSettings(
        duration_s=(total + 0.5) / fs, fs_hz=fs, poincare_phase=None, rtol=1e-9, atol=1e-11))
    np.testing.assert_allclose(steps[1].theta_rad, whole.theta[-steps[1].theta_rad.size:],
                               atol=1e-6)


def test_regime_changes_are_placed_between_steps():
    settings = [0.02, 0.04, 0.06, 0.08, 0.10, 0.08, 0.06, 0.04, 0.02]
    directions = [UP] * 5 + [DOWN] * 4
    regimes = ["period-1", "period-2", "period-2", "chaotic", "chaotic",
               "undetermined", "period-2", "period-1", "period-1"]
    changes = regime_changes(settings, directions, regimes)
    assert [(c.kind, c.direction, c.before, c.after) for c in changes] == [
        ("period-doubling", UP, 0.02, 0.04),
        ("onset of chaos", UP, 0.06, 0.08),
        ("jump", DOWN, 0.10, 0.06),  # the undetermined step between is passed over
        ("jump", DOWN, 0.06, 0.04),
    ]
    assert changes[0].at == pytest.approx(0.03)
    # hysteresis: the same change met at different places up and down
    assert changes[3].at == pytest.approx(0.05)


def _result_bytes(comparisons) -> bytes:
    parts = []
    for comparison in comparisons:
        for step in comparison.simulated:
            parts += [step.theta_rad.tobytes(), step.theta_dot_rad_s.tobytes(),
                      np.array([step.dwell_phase_rad, *step.end_state]).tobytes()]
        for judged in comparison.judged:
            parts += [judged.short.encode(), judged.cloud.tobytes()]
        parts.append(np.array([s.distance for s in comparison.steps]).tobytes())
    return b"".join(parts)


def test_a_local_cluster_of_processes_gives_the_same_bytes(clean, measured):
    model = truth_model(clean.truth)
    cases = [(name, m, clean.sweep, measured, _start(clean))
             for name, m in (("true", model),
                             ("wrong", model.with_extension("barrier_offset", theta_b_rad=0.02)))]
    here = compare_diagrams(cases)
    with MapRunner(workers=2) as runner:
        assert runner.workers == 2
        there = compare_diagrams(cases, runner.map)
    assert [c.summary() for c in there] == [c.summary() for c in here]
    assert _result_bytes(there) == _result_bytes(here)


def test_the_figure_draws_each_model_over_the_measured_points(tmp_path, clean, measured):
    model = truth_model(clean.truth)
    comparisons = [compare_diagram(name, m, clean.sweep, measured, start=_start(clean))
                   for name, m in (("baseline", model.with_extension("excitation_amplitude",
                                                                      eps=0.15)),
                                   ("explained", model))]
    path = draw_diagrams(comparisons, measured, tmp_path / "diagram.png", title="sweep 5")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="no model"):
        draw_diagrams([], measured, tmp_path / "none.png")


def test_the_models_orbit_starts_where_the_first_step_settled(tmp_path, clean, measured):
    model = truth_model(clean.truth)
    comparison = compare_diagram("true", model, clean.sweep, measured, start=_start(clean))
    orbits = model_orbits(comparison, model, clean.sweep, max_points=8)
    branch = orbits.branches[0]
    assert branch.periods == 1 and branch.values[0] == pytest.approx(4.0)
    assert branch.points[0].stable
    measured_theta = np.mean(measured[0].cloud[:, 0])
    assert abs(branch.points[0].section_theta[0] - measured_theta) < 5 * measured[0].noise_rad
    assert np.all(np.diff(branch.values) > 0)  # followed towards the top setting
    path = draw_diagrams([comparison], measured, tmp_path / "orbits.png", orbits=orbits,
                         orbits_of="true")
    assert path.stat().st_size > 0
