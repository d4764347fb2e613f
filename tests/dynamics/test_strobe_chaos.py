"""Chaos tests on strobe points when the chaos lives in bands about a periodic orbit.

Oracles: the logistic map at r = 4 and the Henon map (exponent 0.419 per iteration) are
chaotic, a rotation by an irrational angle is not, white noise has no dynamics.  Each is
put on a periodic skeleton of bands, as a section of banded chaos shows, and read with
noise in 8 phases, as the strobe gives it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dynamics import zero_one_test
from analysis.dynamics.strobe_chaos import (
    Bands,
    bands_from_recurrence,
    neighbour_divergence,
    zero_one_about_bands,
)
from tests.dynamics.integrators import iterate_map
from tests.dynamics.reference_systems import HENON_CLASSIC, henon_map

SEEDS = (11, 12, 13)
PERIODS = 600
PHASES = 8
NOISE_RAD = 1e-3
HENON_EXPONENT = 0.419


def _skeleton(bands: int, rng: np.random.Generator) -> np.ndarray:
    """Band centres of a period-``bands`` orbit, far apart against the noise (8 phases)."""
    return 0.1 * rng.normal(size=(bands, PHASES))


def _noisy(points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return points + NOISE_RAD * rng.normal(size=points.shape)


def _noise_of(points: np.ndarray) -> np.ndarray:
    return np.full(points.shape, NOISE_RAD)


def test_bands_are_the_first_lag_that_recurs_far_better_than_typical():
    recurrence = np.full(32, 100.0)
    recurrence[2::3] = 40.0  # lags 3, 6, 9, ...
    recurrence[5::6] = 10.0  # sub-bands: lags 6, 12, ... recur best
    assert bands_from_recurrence(recurrence) == Bands(period=3, skeleton_period=6)
    assert bands_from_recurrence(np.full(32, 100.0)) == Bands(1, 1)
    recurrence[20:] = np.inf  # lags the record could not test
    assert bands_from_recurrence(recurrence) == Bands(3, 6)


@pytest.mark.parametrize("amplitude", [0.005, 0.02])
def test_the_0_1_test_sees_chaos_about_a_periodic_skeleton(amplitude):
    """Logistic-map chaos a fifth to a twentieth of the bands' spread: the skeleton's own
    periodic signal makes the plain 0-1 test read regular; about the bands' means it
    reads chaotic, and a quasi-periodic wobble there still reads regular."""
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        centres = _skeleton(3, rng)[np.arange(PERIODS) % 3, 0]
        logistic = np.empty(PERIODS)
        logistic[0] = rng.uniform(0.1, 0.9)
        for n in range(1, PERIODS):
            logistic[n] = 4.0 * logistic[n - 1] * (1.0 - logistic[n - 1])
        chaotic = centres + amplitude * logistic
        assert zero_one_test(chaotic).K < 0.5
        assert zero_one_about_bands(chaotic, 3) > 0.9
        golden = (math.sqrt(5.0) - 1.0) / 2.0
        wobble = centres + amplitude * np.sin(2 * math.pi * golden * np.arange(PERIODS))
        assert zero_one_about_bands(wobble, 3) < 0.2


def test_neighbours_in_banded_henon_chaos_separate_from_the_noise_floor():
    """Henon chaos in three bands, 10 to 30 times the noise: neighbours never spread over
    the attractor, but they leave the noise floor at about the map's exponent (less:
    the floor flattens the start); noise about the same bands shows no divergence."""
    henon = iterate_map(henon_map, [0.1, 0.1], HENON_CLASSIC, PERIODS, transient=100)
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        centres = _skeleton(3, rng)[np.arange(PERIODS) % 3]
        chaos = _noisy(centres + 0.01 * henon @ rng.normal(size=(2, PHASES)), rng)
        divergence = neighbour_divergence(chaos, _noise_of(chaos), band_period=3)
        assert divergence.diverges, divergence.note
        assert 0.1 < divergence.exponent_per_period < HENON_EXPONENT
        noise_only = _noisy(centres, rng)
        divergence = neighbour_divergence(noise_only, _noise_of(noise_only), band_period=3)
        assert not divergence.diverges
        assert divergence.exponent_per_period is None
        assert "only" in divergence.note


def test_neighbours_in_other_bands_of_a_settling_orbit_are_not_followed():
    """A period-7 orbit approached by a transient as large as the orbit: an early point
    lies near another band's centre, and the two part by the bands' distance once the
    transient dies.  Within its own band a point's neighbour settles with it."""
    k = np.arange(PERIODS)
    angle = 2 * math.pi * np.arange(7) / 7
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        centres = np.zeros((7, PHASES))
        centres[:, 0], centres[:, 1] = 0.05 * np.cos(angle), 0.05 * np.sin(angle)
        transient = 0.1 * 0.995**k
        points = centres[k % 7]
        points[:, 0] += transient * np.cos(1.3 * k)
        points[:, 1] += transient * np.sin(1.3 * k)
        points = _noisy(points, rng)
        assert not neighbour_divergence(points, _noise_of(points), band_period=7).diverges
        assert neighbour_divergence(points, _noise_of(points), band_period=1).diverges


def test_bad_input_is_refused_naming_what_was_wrong():
    points = np.zeros((100, PHASES))
    with pytest.raises(ValueError, match="point_noise_rad"):
        neighbour_divergence(points, np.ones((100, 3)))
    with pytest.raises(ValueError, match="noise finite and > 0"):
        neighbour_divergence(points, np.zeros((100, PHASES)))
    with pytest.raises(ValueError, match="band_period"):
        neighbour_divergence(points, np.ones((100, PHASES)), band_period=0)
    with pytest.raises(ValueError, match="horizon_periods"):
        neighbour_divergence(points, np.ones((100, PHASES)), horizon_periods=100)
    with pytest.raises(ValueError, match="skeleton_period"):
        zero_one_about_bands(np.zeros(100), 0)
