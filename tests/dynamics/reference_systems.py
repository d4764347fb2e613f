"""Textbook chaotic systems with published Lyapunov exponents, as numba functions (test oracles).

Each has a right-hand side (or map) and its Jacobian in the form the Lyapunov
estimators of :mod:`analysis.dynamics.lyapunov` take: ``f(t, y, p) -> array`` and
``jacobian(t, y, p) -> (n, n) array`` (maps take the iteration count as ``t``).
"""

from __future__ import annotations

import numba
import numpy as np

LORENZ_CLASSIC = np.array([10.0, 28.0, 8.0 / 3.0])  # sigma, rho, beta: lambda_1 ~ 0.906
HENON_CLASSIC = np.array([1.4, 0.3])  # a, b: lambda_1 ~ 0.419
LOGISTIC_FULLY_CHAOTIC = np.array([4.0])  # r = 4: lambda = ln 2


@numba.njit(cache=True)
def lorenz_rhs(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Lorenz (1963) flow; p = (sigma, rho, beta)."""
    out = np.empty(3)
    out[0] = p[0] * (y[1] - y[0])
    out[1] = y[0] * (p[1] - y[2]) - y[1]
    out[2] = y[0] * y[1] - p[2] * y[2]
    return out


@numba.njit(cache=True)
def lorenz_jacobian(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`lorenz_rhs`."""
    jac = np.empty((3, 3))
    jac[0, 0], jac[0, 1], jac[0, 2] = -p[0], p[0], 0.0
    jac[1, 0], jac[1, 1], jac[1, 2] = p[1] - y[2], -1.0, -y[0]
    jac[2, 0], jac[2, 1], jac[2, 2] = y[1], y[0], -p[2]
    return jac


@numba.njit(cache=True)
def henon_map(k: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Henon (1976) map; p = (a, b)."""
    out = np.empty(2)
    out[0] = 1.0 - p[0] * y[0] * y[0] + y[1]
    out[1] = p[1] * y[0]
    return out


@numba.njit(cache=True)
def henon_jacobian(k: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`henon_map`."""
    jac = np.empty((2, 2))
    jac[0, 0], jac[0, 1] = -2.0 * p[0] * y[0], 1.0
    jac[1, 0], jac[1, 1] = p[1], 0.0
    return jac


@numba.njit(cache=True)
def logistic_map(k: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Logistic map x -> r x (1 - x); p = (r,)."""
    out = np.empty(1)
    out[0] = p[0] * y[0] * (1.0 - y[0])
    return out


@numba.njit(cache=True)
def logistic_jacobian(k: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Derivative of :func:`logistic_map`."""
    jac = np.empty((1, 1))
    jac[0, 0] = p[0] * (1.0 - 2.0 * y[0])
    return jac
