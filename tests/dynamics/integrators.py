"""Orbits of the reference systems for the tests: fixed-step integrators over numba functions.

``rhs(t, y, p) -> dy/dt`` and ``step(k, y, p) -> y_next`` must be ``numba.njit``
functions; they are compiled into the loops below once per function and process
(numba cannot cache code specialised on a function argument, so these loops are
not cached to disk).
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

JittedFunction = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


def iterate_map(
    step: JittedFunction, y0: np.ndarray, p: np.ndarray, count: int, *, transient: int = 0
) -> np.ndarray:
    """Orbit of a map as a (count, n) array, after dropping ``transient`` iterations."""
    y0 = np.atleast_1d(np.asarray(y0, dtype=float))
    return _iterate(step, y0, np.asarray(p, dtype=float), int(count), int(transient))


def rk4_trajectory(
    rhs: JittedFunction,
    y0: np.ndarray,
    p: np.ndarray,
    dt: float,
    count: int,
    *,
    transient_steps: int = 0,
) -> np.ndarray:
    """Fixed-step RK4 samples (count, n) of a flow, one every ``dt``, after a transient."""
    y0 = np.atleast_1d(np.asarray(y0, dtype=float))
    return _rk4_samples(
        rhs, y0, np.asarray(p, dtype=float), float(dt), int(count), int(transient_steps)
    )


@numba.njit
def _iterate(step, y0, p, count, transient):
    y = y0.copy()
    for k in range(transient):
        y = step(float(k), y, p)
    out = np.empty((count, y.size))
    for k in range(count):
        out[k] = y
        y = step(float(transient + k), y, p)
    return out


@numba.njit
def _rk4_samples(rhs, y0, p, dt, count, transient_steps):
    y = y0.copy()
    t = 0.0
    for _ in range(transient_steps):
        y = rk4_step(rhs, t, y, p, dt)
        t += dt
    out = np.empty((count, y.size))
    for k in range(count):
        out[k] = y
        y = rk4_step(rhs, t, y, p, dt)
        t += dt
    return out


@numba.njit
def rk4_step(rhs, t, y, p, dt):
    """One classical Runge-Kutta step of dy/dt = rhs(t, y, p)."""
    k1 = rhs(t, y, p)
    k2 = rhs(t + 0.5 * dt, y + 0.5 * dt * k1, p)
    k3 = rhs(t + 0.5 * dt, y + 0.5 * dt * k2, p)
    k4 = rhs(t + dt, y + dt * k3, p)
    return y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
