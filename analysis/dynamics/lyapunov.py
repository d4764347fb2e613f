"""Largest Lyapunov exponent: from equations (tangent dynamics) and from a measured record.

* Maps and flows given as numba functions with their Jacobian: a tangent vector is
  carried along the orbit and renormalised (Benettin et al.); the exponent is the
  mean log growth.
* The impact-pendulum model: same idea with fixed-step RK4 and the tangent obtained by
  central differences of the compiled ``acceleration``; the Hertz contact force is C1,
  so the variational equation holds through contact when the step resolves contact.
* Data: Rosenstein et al. (1993) on a delay embedding, with the straight part of the
  mean log-divergence curve found automatically.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from analysis.dynamics.embedding import delay_embed
from analysis.model import acceleration
from analysis.packed import P

# a numba.njit function f(t, y, p) -> array: a flow's right-hand side, a map's step (t the
# iteration count), or either's Jacobian
JittedFunction = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class LyapunovEstimate:
    """Largest Lyapunov exponent and the curve it came from.

    ``exponent`` is per unit of ``time`` (per second for records and the model, per
    iteration for maps).  For the tangent methods ``curve`` is the running estimate;
    for Rosenstein it is the mean log divergence, fitted over ``fit_range``.
    """

    exponent: float
    method: str
    time: np.ndarray
    curve: np.ndarray
    fit_range: tuple[float, float] | None = None


# --------------------------------------------------------------------------- maps and flows


def map_lyapunov(
    step: JittedFunction,
    jacobian: JittedFunction,
    y0: np.ndarray,
    p: np.ndarray,
    *,
    iterations: int = 200_000,
    transient: int = 1_000,
) -> LyapunovEstimate:
    """Largest exponent [per iteration] of the map ``y -> step(k, y, p)``."""
    if iterations < 10:
        raise ValueError(f"iterations = {iterations}: need at least 10")
    y0 = np.atleast_1d(np.asarray(y0, dtype=float))
    running = _map_tangent(
        step, jacobian, y0, np.asarray(p, dtype=float), int(iterations), int(transient)
    )
    stride = max(1, iterations // 500)
    index = np.arange(stride - 1, iterations, stride)
    return LyapunovEstimate(float(running[-1]), "tangent map", index + 1.0, running[index])


def flow_lyapunov(
    rhs: JittedFunction,
    jacobian: JittedFunction,
    y0: np.ndarray,
    p: np.ndarray,
    *,
    dt: float,
    duration: float,
    transient: float = 0.0,
) -> LyapunovEstimate:
    """Largest exponent [per unit time] of dy/dt = rhs(t, y, p): RK4 on trajectory and tangent."""
    if not dt > 0 or not duration > dt:
        raise ValueError(f"need 0 < dt < duration, got dt = {dt}, duration = {duration}")
    steps = round(duration / dt)
    y0 = np.atleast_1d(np.asarray(y0, dtype=float))
    running = _flow_tangent(
        rhs,
        jacobian,
        y0,
        np.asarray(p, dtype=float),
        float(dt),
        steps,
        round(transient / dt),
    )
    stride = max(1, steps // 500)
    index = np.arange(stride - 1, steps, stride)
    return LyapunovEstimate(float(running[-1]), "variational RK4", (index + 1) * dt, running[index])


@numba.njit(cache=True)
def _matvec(matrix, vector):
    """matrix @ vector as a plain loop (the generic matmul costs seconds of compile time)."""
    out = np.zeros(matrix.shape[0])
    for i in range(matrix.shape[0]):
        for j in range(matrix.shape[1]):
            out[i] += matrix[i, j] * vector[j]
    return out


@numba.njit
def _map_tangent(step, jacobian, y0, p, iterations, transient):
    y = y0.copy()
    for k in range(transient):
        y = step(float(k), y, p)
    v = np.ones(y.size) / math.sqrt(y.size)
    total = 0.0
    running = np.empty(iterations)
    for k in range(iterations):
        v = _matvec(jacobian(float(k), y, p), v)
        y = step(float(k), y, p)
        norm = math.sqrt(np.sum(v * v))
        total += math.log(norm)
        v /= norm
        running[k] = total / (k + 1)
    return running


@numba.njit
def _flow_tangent(rhs, jacobian, y0, p, dt, steps, transient_steps):
    y = y0.copy()
    t = 0.0
    for _ in range(transient_steps):
        k1 = rhs(t, y, p)
        k2 = rhs(t + 0.5 * dt, y + 0.5 * dt * k1, p)
        k3 = rhs(t + 0.5 * dt, y + 0.5 * dt * k2, p)
        k4 = rhs(t + dt, y + dt * k3, p)
        y = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        t += dt
    v = np.ones(y.size) / math.sqrt(y.size)
    total = 0.0
    running = np.empty(steps)
    for k in range(steps):
        # RK4 on the joint system (y, v), v' = J(t, y) v
        k1 = rhs(t, y, p)
        l1 = _matvec(jacobian(t, y, p), v)
        y2, v2 = y + 0.5 * dt * k1, v + 0.5 * dt * l1
        k2 = rhs(t + 0.5 * dt, y2, p)
        l2 = _matvec(jacobian(t + 0.5 * dt, y2, p), v2)
        y3, v3 = y + 0.5 * dt * k2, v + 0.5 * dt * l2
        k3 = rhs(t + 0.5 * dt, y3, p)
        l3 = _matvec(jacobian(t + 0.5 * dt, y3, p), v3)
        y4, v4 = y + dt * k3, v + dt * l3
        k4 = rhs(t + dt, y4, p)
        l4 = _matvec(jacobian(t + dt, y4, p), v4)
        y = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        v = v + dt / 6.0 * (l1 + 2.0 * l2 + 2.0 * l3 + l4)
        t += dt
        norm = math.sqrt(np.sum(v * v))
        total += math.log(norm)
        v /= norm
        running[k] = total / ((k + 1) * dt)
    return running


# --------------------------------------------------------------------------- the pendulum model


def model_lyapunov(
    p: np.ndarray,
    theta0: float,
    theta_dot0: float,
    *,
    duration_s: float,
    transient_s: float = 0.0,
    steps_per_period: int | None = None,
    t0_s: float = 0.0,
) -> LyapunovEstimate:
    """Largest exponent [1/s] of the impact pendulum, packed parameters ``p`` (``Model.pack()``).

    Fixed-step RK4 with ``steps_per_period`` steps per drive period (or per natural
    period when undriven).  The default takes at least 2000 and enough for 100 steps
    per contact (:func:`contact_time_s` at 1 m/s, a hard impact for this rig): the
    tangent of a contact sequence is only right when each contact is resolved.
    The tangent is the directional central difference of ``acceleration``.  Multiply
    by the drive period for the exponent per period.
    """
    p = np.asarray(p, dtype=float)
    if p.shape != (P.SIZE,):
        raise ValueError(f"p must be a packed parameter vector of length {P.SIZE} (Model.pack())")
    if not duration_s > 0 or transient_s < 0:
        raise ValueError("duration_s must be > 0 and transient_s >= 0")
    if p[P.OMEGA_DRIVE] > 0:
        period = 2.0 * math.pi / p[P.OMEGA_DRIVE]
    else:
        period = 2.0 * math.pi / math.sqrt(p[P.OMEGA2])
    if steps_per_period is None:
        steps_per_period = 2000
        if p[P.BARRIER] != 0.0:
            steps_per_period = max(2000, math.ceil(100 * period / contact_time_s(p, 1.0)))
    dt = period / steps_per_period
    steps = round(duration_s / dt)
    running, final = _pendulum_tangent(
        p, float(theta0), float(theta_dot0), float(t0_s), dt, steps, round(transient_s / dt)
    )
    if not np.all(np.isfinite(final)):
        raise FloatingPointError("the pendulum trajectory diverged; reduce the step or the drive")
    stride = max(1, steps // 500)
    index = np.arange(stride - 1, steps, stride)
    return LyapunovEstimate(
        float(running[-1]), "variational RK4 (model)", (index + 1) * dt, running[index]
    )


def contact_time_s(p: np.ndarray, entry_speed_m_s: float) -> float:
    """Hertz contact duration 3.2181 (m_eff^2 / (K^2 v))^(1/5) (docs/MODEL.md section 4 oracle).

    m_eff = m L^2 / l^2 = 1 / (contact gain * l); the law is for exponent 3/2 and no
    damping, which is all a step-size choice needs.
    """
    m_eff = 1.0 / (p[P.CONTACT_GAIN] * p[P.SHAFT_L])
    return 3.2181 * (m_eff**2 / (p[P.K] ** 2 * entry_speed_m_s)) ** 0.2


# Not cached: numba's cache tracks only this file, and these call the model's equations
# from analysis/model.py; a cached copy would keep an old model after that file changed.
@numba.njit
def _pendulum_derivatives(t, th, om, v1, v2, p):
    acc = acceleration(t, th, om, p)
    # directional derivative of theta'' along v (|v| = O(1) after renormalisation)
    h = 1e-7
    plus = acceleration(t, th + h * v1, om + h * v2, p)
    minus = acceleration(t, th - h * v1, om - h * v2, p)
    return om, acc, v2, (plus - minus) / (2.0 * h)


@numba.njit
def _pendulum_tangent(p, theta0, theta_dot0, t0, dt, steps, transient_steps):
    th, om, t = theta0, theta_dot0, t0
    v1, v2 = 1.0 / math.sqrt(2.0), 1.0 / math.sqrt(2.0)
    running = np.empty(steps)
    total = 0.0
    for k in range(transient_steps + steps):
        a1, b1, c1, d1 = _pendulum_derivatives(t, th, om, v1, v2, p)
        a2, b2, c2, d2 = _pendulum_derivatives(
            t + 0.5 * dt,
            th + 0.5 * dt * a1,
            om + 0.5 * dt * b1,
            v1 + 0.5 * dt * c1,
            v2 + 0.5 * dt * d1,
            p,
        )
        a3, b3, c3, d3 = _pendulum_derivatives(
            t + 0.5 * dt,
            th + 0.5 * dt * a2,
            om + 0.5 * dt * b2,
            v1 + 0.5 * dt * c2,
            v2 + 0.5 * dt * d2,
            p,
        )
        a4, b4, c4, d4 = _pendulum_derivatives(
            t + dt, th + dt * a3, om + dt * b3, v1 + dt * c3, v2 + dt * d3, p
        )
        th += dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        om += dt / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        v1 += dt / 6.0 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
        v2 += dt / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
        t += dt
        norm = math.sqrt(v1 * v1 + v2 * v2)
        v1 /= norm
        v2 /= norm
        if k >= transient_steps:
            total += math.log(norm)
            running[k - transient_steps] = total / ((k - transient_steps + 1) * dt)
    final = np.array([th, om])
    return running, final


# --------------------------------------------------------------------------- from data


def rosenstein_lyapunov(
    x: np.ndarray,
    fs_hz: float,
    *,
    dimension: int,
    delay: int,
    theiler_window: int | None = None,
    horizon: int | None = None,
    max_references: int = 4000,
) -> LyapunovEstimate:
    """Largest exponent [1/s] of a scalar record by Rosenstein's method on its delay embedding.

    The nearest neighbour of each of up to ``max_references`` points (at least
    ``theiler_window`` samples away in time; default: one mean period of the record)
    is followed for ``horizon`` samples (default: 4 mean periods); the mean log
    distance grows linearly at rate lambda before saturating at the attractor size.
    The fitted stretch is chosen by :func:`scaling_region`.
    """
    x = np.asarray(x, dtype=float)
    if not fs_hz > 0:
        raise ValueError(f"fs_hz = {fs_hz!r}: must be > 0")
    period = mean_period_samples(x)
    theiler = int(theiler_window if theiler_window is not None else max(period, delay))
    horizon = int(horizon if horizon is not None else max(4 * period, 20))
    vectors = delay_embed(x, dimension, delay)
    n = vectors.shape[0] - horizon
    if n < 10 * dimension:
        raise ValueError(
            f"record too short: {vectors.shape[0]} delay vectors for a horizon of {horizon} samples"
        )
    # Reference points spread evenly over the record; their neighbours come from all of it.
    rows = np.unique(np.linspace(0, n - 1, min(n, max_references)).astype(np.int64))
    pair = _nearest_outside_window(vectors[:n], rows, theiler)
    found = pair >= 0
    rows, pair = rows[found], pair[found]
    if rows.size == 0:
        raise ValueError("no nearest neighbours outside the Theiler window: record too short")
    curve = np.empty(horizon + 1)
    for step in range(horizon + 1):
        d = np.linalg.norm(vectors[rows + step] - vectors[pair + step], axis=1)
        curve[step] = float(np.mean(np.log(d[d > 0])))
    # Chaos spreads neighbours over the whole attractor; regular motion keeps them close.
    rng = np.random.default_rng(0)
    a, b = rng.integers(0, vectors.shape[0], (2, 2000))
    spread = np.linalg.norm(vectors[a] - vectors[b], axis=1)
    attractor_log_size = float(np.mean(np.log(spread[spread > 0])))
    if np.median(curve[int(0.8 * curve.size) :]) < attractor_log_size - 2.0:
        raise ValueError(
            "no exponential divergence: nearest neighbours stay within a few percent of the "
            "attractor size over the horizon (periodic or quasi-periodic motion, or a horizon "
            "too short for a slow exponent)"
        )
    start, stop = scaling_region(curve)
    steps = np.arange(horizon + 1)
    slope = np.polyfit(steps[start:stop], curve[start:stop], 1)[0]
    time = steps / fs_hz
    return LyapunovEstimate(
        float(slope * fs_hz), "Rosenstein", time, curve, (time[start], time[stop - 1])
    )


@numba.njit(cache=True)
def _nearest_outside_window(vectors, rows, theiler):
    """Nearest neighbour of each vectors[rows[i]] among all vectors more than ``theiler`` apart.

    A brute-force scan: a k-d tree would have to return ~2 theiler candidates per
    query before the first one outside the window, which costs more.  Exact
    duplicates are skipped (log 0); -1 where no neighbour exists.
    """
    n, dim = vectors.shape
    out = np.full(rows.size, -1, dtype=np.int64)
    for r in range(rows.size):
        i = rows[r]
        best = np.inf
        for j in range(n):
            if abs(i - j) <= theiler:
                continue
            d2 = 0.0
            for c in range(dim):
                diff = vectors[i, c] - vectors[j, c]
                d2 += diff * diff
            if 0.0 < d2 < best:
                best = d2
                out[r] = j
    return out


def scaling_region(curve: np.ndarray, *, low: float = 0.1, high: float = 0.6) -> tuple[int, int]:
    """Index range [start, stop) of the linear growth of a log-divergence curve.

    The curve rises from its start y0 to a plateau y_sat (the attractor size); the
    fit uses the stretch from where it has covered ``low`` of that rise to where it
    first covers ``high`` — past the initial alignment with the unstable direction
    and before saturation bends it.  At least 4 points are kept.
    """
    curve = np.asarray(curve, dtype=float)
    tail = curve[int(0.8 * curve.size) :]
    y0, y_sat = curve[0], float(np.median(tail))
    rise = y_sat - y0
    if not rise > 0:
        raise ValueError("the divergence curve does not grow: no positive exponent to fit")
    above_low = np.flatnonzero(curve >= y0 + low * rise)
    above_high = np.flatnonzero(curve >= y0 + high * rise)
    start = int(above_low[0]) if above_low.size else 0
    stop = int(above_high[0]) + 1 if above_high.size else curve.size
    if stop - start < 4:
        stop = min(curve.size, start + 4)
    return start, stop


def mean_period_samples(x: np.ndarray) -> int:
    """Mean period [samples] of a record: 1 / its power-weighted mean frequency."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    power = np.abs(np.fft.rfft(x)) ** 2
    frequency = np.fft.rfftfreq(x.size)
    mean_frequency = float(np.sum(frequency[1:] * power[1:]) / max(np.sum(power[1:]), 1e-300))
    return round(1.0 / mean_frequency) if mean_frequency > 0 else x.size
