"""The 0-1 test: K ~ 0 for regular motion, K ~ 1 for chaos."""

from __future__ import annotations

import numpy as np

from analysis.dynamics import zero_one_test
from tests.dynamics.integrators import iterate_map
from tests.dynamics.reference_systems import LOGISTIC_FULLY_CHAOTIC, logistic_map

K = np.arange(1000)


def test_periodic_signal_gives_k_near_zero():
    period_3 = np.sin(2 * np.pi * K / 3) + 0.3 * np.cos(4 * np.pi * K / 3)
    assert abs(zero_one_test(period_3).K) < 0.1


def test_quasi_periodic_signal_gives_k_near_zero():
    golden = (np.sqrt(5.0) - 1.0) / 2.0
    quasi = np.sin(2 * np.pi * golden * K) + 0.5 * np.sin(2 * np.pi * np.sqrt(2.0) * K)
    assert abs(zero_one_test(quasi).K) < 0.1


def test_logistic_map_at_r4_gives_k_near_one():
    orbit = iterate_map(logistic_map, [0.3], LOGISTIC_FULLY_CHAOTIC, 1000, transient=100)[:, 0]
    assert zero_one_test(orbit).K > 0.9


def test_henon_gives_k_near_one(henon_orbit):
    assert zero_one_test(henon_orbit[:1000, 0]).K > 0.9


def test_result_is_reproducible_with_its_seed():
    orbit = iterate_map(logistic_map, [0.3], LOGISTIC_FULLY_CHAOTIC, 500, transient=100)[:, 0]
    a, b = zero_one_test(orbit, seed=3), zero_one_test(orbit, seed=3)
    assert np.array_equal(a.K_per_c, b.K_per_c)
    assert not np.array_equal(a.c_values, zero_one_test(orbit, seed=4).c_values)
