"""Shared reference trajectories for the dynamics tests (computed once per session)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.dynamics.integrators import iterate_map, rk4_trajectory
from tests.dynamics.reference_systems import (
    HENON_CLASSIC,
    LORENZ_CLASSIC,
    henon_map,
    lorenz_rhs,
)

LORENZ_DT = 0.01


@pytest.fixture(scope="session")
def lorenz_x() -> np.ndarray:
    """x of the classic Lorenz attractor, 20 000 samples at dt = 0.01 after a transient."""
    trajectory = rk4_trajectory(
        lorenz_rhs, [1.0, 1.0, 1.0], LORENZ_CLASSIC, LORENZ_DT, 20_000, transient_steps=2_000
    )
    return trajectory[:, 0]


@pytest.fixture(scope="session")
def henon_orbit() -> np.ndarray:
    """2000 points of the Henon attractor (a = 1.4, b = 0.3)."""
    return iterate_map(henon_map, [0.1, 0.1], HENON_CLASSIC, 2_000, transient=200)
