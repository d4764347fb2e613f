"""Independent reference free decays: scipy's DOP853 on the pendulum ODE, no barrier.

Only free motion without barrier is integrated here, an independent method for
the free-decay fits (the impact tests use the project's simulator).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def free_decay(
    theta0: float, zeta: float, L_m: float, *, duration_s: float, fs_hz: float,
    g: float = 9.81, theta_dot0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """theta'' + 2 zeta omega theta' + omega^2 sin(theta) = 0 sampled at fs_hz from t = 0."""
    omega = np.sqrt(g / L_m)
    t = np.arange(round(duration_s * fs_hz)) / fs_hz

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], -2.0 * zeta * omega * y[1] - omega**2 * np.sin(y[0])]

    sol = solve_ivp(rhs, (0.0, t[-1]), [theta0, theta_dot0], t_eval=t, method="DOP853",
                    rtol=1e-11, atol=1e-13)
    return t, sol.y[0]
