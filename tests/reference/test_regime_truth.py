"""The periods a noisy record can show, on constructed stroboscopic points."""

from __future__ import annotations

import numpy as np
import pytest

from reference.regime_truth import RegimeTruth, periods_a_record_shows

NOISE = 1e-3


def _points(pattern: list[float], n: int = 200) -> np.ndarray:
    """Stroboscopic (theta, theta') points repeating ``pattern`` in theta."""
    theta = np.resize(np.asarray(pattern), n)
    return np.column_stack([theta, np.zeros(n)])


def test_a_splitting_below_the_noise_lets_the_divisor_count():
    truth = RegimeTruth("period-2", 2, None, 0.0)
    hidden = _points([0.1, 0.1 + 0.02 * NOISE])
    assert periods_a_record_shows(hidden, NOISE, truth) == {1, 2}


def test_a_splitting_the_record_resolves_leaves_only_the_true_period():
    truth = RegimeTruth("period-4", 4, None, 0.0)
    shown = _points([0.1, 0.1 + 0.5 * NOISE, 0.1 + 0.01 * NOISE, 0.1 + 0.51 * NOISE])
    assert periods_a_record_shows(shown, NOISE, truth) == {2, 4}
    resolved = _points([0.1, 0.2, 0.1 + 0.5 * NOISE, 0.2])
    assert periods_a_record_shows(resolved, NOISE, truth) == {4}


def test_chaos_that_ends_periodic_shows_its_final_period():
    rng = np.random.default_rng(3)
    theta = np.concatenate([rng.uniform(-0.2, 0.2, 150), np.resize([0.05, -0.07, 0.01], 90)])
    points = np.column_stack([theta, np.zeros_like(theta)])
    truth = RegimeTruth("chaotic", None, 5.0, None)
    assert periods_a_record_shows(points, NOISE, truth) == {3}
    chaotic = np.column_stack([rng.uniform(-0.2, 0.2, 240), np.zeros(240)])
    assert periods_a_record_shows(chaotic, NOISE, truth) == set()


def test_noise_must_be_stated():
    with pytest.raises(ValueError, match="noise_rad"):
        periods_a_record_shows(_points([0.1]), 0.0, RegimeTruth("periodic", 1, None, 0.0))
