"""The 0-1 test: K ~ 0 for regular motion, K ~ 1 for chaos."""

from __future__ import annotations

import numpy as np

from analysis.dynamics import zero_one_test
from analysis.dynamics.chaos01 import zero_one_k
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


def test_many_series_at_once_give_each_series_its_own_k(henon_orbit):
    logistic = iterate_map(logistic_map, [0.3], LOGISTIC_FULLY_CHAOTIC, 200, transient=100)[:, 0]
    rows = np.array([logistic, henon_orbit[:200, 0], np.sin(2 * np.pi * K[:200] / 3),
                     np.full(200, 0.7)])  # the last constant: a fixed point, K = 0
    expected = [zero_one_test(row).K for row in rows]
    assert zero_one_k(rows).tolist() == expected  # the same numbers, to the last bit
    assert expected[3] == 0.0 and expected[0] > 0.9
