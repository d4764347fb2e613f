"""Delay from mutual information, dimension from false nearest neighbours."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.dynamics import (
    delay_embed,
    fnn_dimension,
    mutual_information,
    mutual_information_delay,
)


@pytest.mark.parametrize("period_samples", [37.3, 100.0, 161.7])
def test_mutual_information_delay_of_a_sine_is_a_quarter_period(period_samples):
    # a measured sine carries a little noise; a noiseless one makes the histogram MI degenerate
    rng = np.random.default_rng(11)
    t = np.arange(20_000)
    x = np.sin(2 * np.pi * t / period_samples) + 0.01 * rng.normal(size=t.size)
    choice = mutual_information_delay(x, max_lag=int(0.6 * period_samples))
    assert abs(choice.delay - period_samples / 4) <= max(1.0, 0.06 * period_samples)


def test_mutual_information_of_independent_noise_is_near_zero_and_of_itself_is_entropy():
    rng = np.random.default_rng(7)
    x = rng.uniform(size=50_000)
    mi = mutual_information(x, 3, bins=16)
    assert mi[0] == pytest.approx(np.log(16), rel=0.01)  # uniform over 16 bins
    assert np.all(mi[1:] < 0.01)


def test_fnn_gives_dimension_three_for_lorenz_x(lorenz_x):
    delay = mutual_information_delay(lorenz_x, max_lag=100).delay
    choice = fnn_dimension(lorenz_x, delay, max_dimension=6)
    assert choice.dimension == 3
    assert choice.false_fraction[0] > 0.5  # one coordinate folds the attractor onto itself


def test_fnn_gives_dimension_one_or_two_for_a_sine():
    t = np.arange(5000)
    x = np.sin(2 * np.pi * t / 50)
    choice = fnn_dimension(x, 12, max_dimension=5)
    assert choice.dimension <= 2


def test_delay_embed_rows_are_delayed_copies():
    x = np.arange(20.0)
    vectors = delay_embed(x, 3, 4)
    assert vectors.shape == (12, 3)
    assert np.array_equal(vectors[5], [5.0, 9.0, 13.0])


def test_bad_input_is_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="NaN"):
        mutual_information_delay(np.array([0.0, np.nan] * 20))
    with pytest.raises(ValueError, match="too short"):
        delay_embed(np.arange(20.0), 5, 6)
