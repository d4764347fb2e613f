"""The classical alternative to finite-time contact: instantaneous impacts with a constant
coefficient of restitution e.

Between impacts the pendulum swings freely (viscous damping, full gravity term);
when it reaches the barrier at theta = theta_b moving towards it, its velocity is
reversed and multiplied by e.  Once the rebound speed is too small to leave the
barrier again within a step, it rests there.  The paper argues that this model
misses what a viscoelastic barrier does; fitting both to the same impact decay
measures by how much.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from analysis import quantities as q

SUBSTEPS = 8  # RK4 steps per sample period; the swing is resolved far below its period


@numba.njit(cache=True)
def _rhs(theta: float, omega_dot: float, omega2: float, two_zeta_omega: float) -> float:
    return -two_zeta_omega * omega_dot - omega2 * math.sin(theta)


@numba.njit(cache=True)
def restitution_samples(
    theta0: float, theta_dot0: float, omega: float, zeta: float, e: float, theta_b: float,
    dt: float, n: int,
) -> np.ndarray:
    """Sampled angle of the impact pendulum with instantaneous impacts (restitution e)."""
    out = np.empty(n)
    omega2 = omega * omega
    tzo = 2.0 * zeta * omega
    h = dt / SUBSTEPS
    th, om = theta0, theta_dot0
    resting = False
    for i in range(n):
        out[i] = th
        if resting:
            continue
        for _ in range(SUBSTEPS):
            k1t, k1o = om, _rhs(th, om, omega2, tzo)
            k2t = om + 0.5 * h * k1o
            k2o = _rhs(th + 0.5 * h * k1t, k2t, omega2, tzo)
            k3t = om + 0.5 * h * k2o
            k3o = _rhs(th + 0.5 * h * k2t, k3t, omega2, tzo)
            k4t = om + h * k3o
            k4o = _rhs(th + h * k3t, k4t, omega2, tzo)
            new_th = th + h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
            new_om = om + h / 6.0 * (k1o + 2.0 * k2o + 2.0 * k3o + k4o)
            if new_th > theta_b and om > 0.0:
                # Locate the crossing on the cubic Hermite interpolant by bisection.
                lo, hi = 0.0, 1.0
                for _ in range(40):
                    s = 0.5 * (lo + hi)
                    h00 = 2 * s**3 - 3 * s**2 + 1
                    h10 = s**3 - 2 * s**2 + s
                    h01 = -2 * s**3 + 3 * s**2
                    h11 = s**3 - s**2
                    val = h00 * th + h10 * h * om + h01 * new_th + h11 * h * new_om
                    if val > theta_b:
                        hi = s
                    else:
                        lo = s
                s = 0.5 * (lo + hi)
                v_in = om + s * (new_om - om)
                v_out = -e * v_in
                th = theta_b
                om = v_out
                # rest on the barrier when gravity brings it back within a fraction of a step
                if abs(v_out) * h < 1e-12 or (theta_b >= 0.0 and abs(v_out) < 1e-6):
                    om = 0.0
                    resting = theta_b >= 0.0
                    break
                # finish the remaining part of the substep in free flight (explicit Euler is
                # enough for a fraction of a tiny step)
                rest = (1.0 - s) * h
                acc = _rhs(th, om, omega2, tzo)
                th = th + om * rest + 0.5 * acc * rest * rest
                om = om + acc * rest
                if th > theta_b:
                    th = theta_b
            else:
                th, om = new_th, new_om
    return out


def restitution_from_hunt_crossley(mu0_s_per_m: float, l_m: float, speed_rad_s: float) -> float:
    """Start value: e = 1 - (2/3) mu0 v at the contact-point speed v = l theta'
    (docs/MODEL.md section 4)."""
    return float(min(max(1.0 - 2.0 / 3.0 * mu0_s_per_m * l_m * abs(speed_rad_s), 0.05), 0.99))


def _curve(x: np.ndarray, dt: float, n: int, theta_b: float) -> np.ndarray:
    theta0, theta_dot0, omega, zeta, e = x
    return restitution_samples(theta0, theta_dot0, omega, zeta, e, theta_b, dt, n)


def fit_restitution(
    t: np.ndarray, y: np.ndarray, valid: np.ndarray, start: dict[str, float], n_train: int,
    theta_b: float = 0.0,
) -> dict[str, object]:
    """Fit theta0, theta'0, omega, zeta and e on the first ``n_train`` samples and on all.

    Returns the full-record values with 95 % intervals, the residual and the held-out
    prediction error of the training fit on the samples after ``n_train``.
    """
    from scipy.optimize import least_squares

    from analysis.identify.intervals import Z95, sandwich_covariance

    dt = float(t[1] - t[0])
    x0 = np.array([
        start[q.theta0_rad], start[q.theta_dot0_rad_s], start[q.omega_rad_s],
        max(start[q.zeta], 1e-5), start[q.e],
    ])
    lower = [-math.pi / 2, -np.inf, 0.5 * x0[2], 0.0, 0.0]
    upper = [math.pi / 2, np.inf, 2.0 * x0[2], 0.5, 1.0]
    x0 = np.clip(x0, lower, upper)

    def solve(n: int, x_start: np.ndarray):
        mask = valid[:n]
        target = y[:n][mask]

        def residual(x: np.ndarray) -> np.ndarray:
            return _curve(x, dt, n, theta_b)[mask] - target

        return least_squares(residual, x_start, bounds=(lower, upper), method="trf",
                             x_scale="jac", max_nfev=200)

    train = solve(n_train, x0)
    prediction = _curve(train.x, dt, t.size, theta_b)
    tail = valid.copy()
    tail[:n_train] = False
    heldout = float(np.sqrt(np.mean((prediction[tail] - y[tail]) ** 2))) if tail.any() else math.nan
    full = solve(t.size, train.x)
    cov = sandwich_covariance([(full.fun, full.jac)])
    names = (q.theta0_rad, q.theta_dot0_rad_s, q.omega_rad_s, q.zeta, q.e)
    estimates = {}
    for i, name in enumerate(names):
        half = Z95 * math.sqrt(max(cov.matrix[i, i], 0.0))
        estimates[name] = {"value": float(full.x[i]),
                           "ci95": [float(full.x[i] - half), float(full.x[i] + half)]}
    curve = _curve(full.x, dt, t.size, theta_b)
    residual = np.where(valid, curve - np.where(valid, y, 0.0), np.nan)
    return {
        "parameters": estimates,
        "values": dict(zip(names, full.x.tolist(), strict=True)),
        "residual": residual,
        "curve": curve,
        "rss": float(full.fun @ full.fun),
        "n_params": len(names),
        "heldout_rms": heldout,
    }
