"""Lyapunov exponents: from equations (tangent dynamics) and from a measured record.

* Maps and flows given as numba functions with their Jacobian: a tangent vector is
  carried along the orbit and renormalised (Benettin et al.); the exponent is the
  mean log growth.
* The impact-pendulum model: both exponents by the QR method on the exact sensitivities of
  the compiled integrator's runs (through every contact), one interval at a time.
* Data: Rosenstein et al. (1993) on a delay embedding, with the straight part of the
  mean log-divergence curve found automatically.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from analysis.dynamics.embedding import delay_embed
from analysis.packed import P
from analysis.simulate.sensitivity import (
    DEFAULT_SENSITIVITY_SETTINGS,
    SensitivitySettings,
    simulate_sensitivities,
)

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


SPECTRUM_METHOD = "QR on the variational flow (model)"


@dataclass(frozen=True)
class SpectrumSettings:
    """How :func:`model_lyapunov_spectrum` runs.

    ``duration_s`` of measured flow after ``transient_s`` (during which the frame already
    turns toward the growing directions, but nothing is counted), both in whole intervals
    of ``interval_s`` (rounded; None: one drive period, or one small-angle natural period
    when the model is undriven); the integrator's tolerances ``rtol`` and ``atol``.
    Refused with ValueError, naming the setting, when not usable.
    """

    duration_s: float
    transient_s: float = 0.0
    interval_s: float | None = None
    rtol: float = DEFAULT_SENSITIVITY_SETTINGS.rtol
    atol: float = DEFAULT_SENSITIVITY_SETTINGS.atol

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"duration_s = {self.duration_s!r}: must be finite and > 0")
        if not (math.isfinite(self.transient_s) and self.transient_s >= 0):
            raise ValueError(f"transient_s = {self.transient_s!r}: must be finite and >= 0")
        if self.interval_s is not None and not (
            math.isfinite(self.interval_s) and 0 < self.interval_s <= self.duration_s
        ):
            raise ValueError(
                f"interval_s = {self.interval_s!r}: must be finite, > 0 and at most "
                f"duration_s = {self.duration_s!r}"
            )
        SensitivitySettings(rtol=self.rtol, atol=self.atol)  # refuses bad tolerances


@dataclass(frozen=True)
class LyapunovSpectrum:
    """Both Lyapunov exponents of the impact pendulum's flow and how they settled.

    ``exponents_per_s`` in the order of the QR frame (the first is the largest once the
    frame has turned toward the fastest-growing direction); ``period_s`` the drive period
    (the small-angle natural period when undriven); ``time`` the measured time at the end
    of each interval [s] and ``running`` (interval, exponent) the running averages there
    [1/s]; ``t`` and ``states`` the time [s] and state (theta, theta') at the start of the
    measured stretch and at every interval's end (the stroboscopic section when the
    interval is the drive period).
    """

    exponents_per_s: np.ndarray
    period_s: float
    interval_s: float
    time: np.ndarray
    running: np.ndarray
    t: np.ndarray
    states: np.ndarray
    method: str = SPECTRUM_METHOD

    @property
    def exponents_per_period(self) -> np.ndarray:
        """The exponents per drive period (per natural period when undriven)."""
        return self.exponents_per_s * self.period_s

    @property
    def largest(self) -> LyapunovEstimate:
        """The first exponent [1/s] with its running average, as the other estimators give."""
        return LyapunovEstimate(
            float(self.exponents_per_s[0]), self.method, self.time, self.running[:, 0]
        )


def model_lyapunov_spectrum(
    p: np.ndarray,
    theta0: float,
    theta_dot0: float,
    settings: SpectrumSettings,
    *,
    t0_s: float = 0.0,
) -> LyapunovSpectrum:
    """Both Lyapunov exponents of the impact pendulum, packed parameters ``p``
    (``Model.pack()``), from (theta0, theta_dot0) at ``t0_s``, by the QR (Benettin) method.

    Each interval is one run of the compiled integrator with the sensitivities of its end
    state to its start state (:func:`analysis.simulate.simulate_sensitivities`: exact through
    every contact), restarted from the end state of the one before.  That Jacobian, in the
    units (theta, theta' / Omega), carries an orthonormal frame, which QR factorisation
    makes orthonormal again; the logarithms of the diagonal of R, summed and divided by the
    time, are the exponents.  The flow is 2-D and non-autonomous (the drive phase is time,
    not a state), so there are two exponents and their sum is the time average of the
    divergence of (theta', theta'').  The integrator chooses its steps for the state alone:
    a swing that decays to the size of ``atol`` is stepped coarsely, and the frame with
    it.  RuntimeError when a run stops (over the top).
    """
    p = np.ascontiguousarray(p, dtype=float)
    if p.shape != (P.SIZE,):
        raise ValueError(f"p must be a packed parameter vector of length {P.SIZE} (Model.pack())")
    driven = p[P.OMEGA_DRIVE] > 0
    rate = float(p[P.OMEGA_DRIVE] if driven else math.sqrt(p[P.OMEGA2]))
    period = 2.0 * math.pi / rate
    interval = float(settings.interval_s if settings.interval_s is not None else period)
    n_transient = round(settings.transient_s / interval)
    n = max(1, round(settings.duration_s / interval))
    sensitivity = SensitivitySettings(rtol=settings.rtol, atol=settings.atol)
    frame = np.eye(2)
    logs = np.empty((n, 2))
    t = np.empty(n + 1)
    states = np.empty((n + 1, 2))
    th, om = float(theta0), float(theta_dot0)
    start = float(t0_s)
    for k in range(n_transient + n):
        if k >= n_transient:
            t[k - n_transient], states[k - n_transient] = start, (th, om)
        end = t0_s + (k + 1) * interval
        run = simulate_sensitivities(p, th, om, np.array([end]), t0=start, settings=sensitivity)
        if run.status != "ok":
            raise RuntimeError(
                f"the run stopped ({run.status}) in the interval from t = {start:.6g} s, "
                f"(theta, theta') = ({th:.6g}, {om:.6g})"
            )
        jacobian = run.jacobian[0, :, :2]
        # in (theta, theta' / rate): both components of a swing of comparable size
        scaled = np.array([[jacobian[0, 0], jacobian[0, 1] * rate],
                           [jacobian[1, 0] / rate, jacobian[1, 1]]])
        frame, growth = _qr_2x2(scaled @ frame)
        if k >= n_transient:
            logs[k - n_transient] = growth
        th, om, start = float(run.theta[0]), float(run.theta_dot[0]), end
    t[n], states[n] = start, (th, om)
    time = (np.arange(n) + 1.0) * interval
    running = np.cumsum(logs, axis=0) / time[:, None]
    return LyapunovSpectrum(running[-1].copy(), period, interval, time, running, t, states)


CONVERGENCE_BATCHES = 10  # batch means of the exponents: their standard error


def spectrum_report(spectrum: LyapunovSpectrum) -> dict[str, Any]:
    """The spectrum as plain values (a command's JSON): its method; the exponents per second
    and per period (per drive period, per small-angle natural period undriven); the span
    measured (``from_s`` to ``to_s`` of the run's time, in ``intervals`` intervals of
    ``interval_s``); and how far it has settled: ``standard_error_per_period``, the
    batch-means standard error of each exponent (``CONVERGENCE_BATCHES`` batches of whole
    intervals; None with fewer than two intervals a batch), and
    ``change_over_last_half_per_period``, how much the running averages moved over the
    second half of the span."""
    n = spectrum.time.size
    totals = spectrum.running * spectrum.time[:, None]  # the summed log growth to each end
    per_interval = np.diff(np.vstack([np.zeros(2), totals]), axis=0)
    errors = None
    if n >= 2 * CONVERGENCE_BATCHES:
        means = np.array([chunk.mean(axis=0) for chunk in
                          np.array_split(per_interval, CONVERGENCE_BATCHES)])
        errors = (means.std(axis=0, ddof=1) / math.sqrt(CONVERGENCE_BATCHES)
                  * spectrum.period_s / spectrum.interval_s)
    change = (spectrum.running[-1] - spectrum.running[n // 2 - 1]) * spectrum.period_s \
        if n >= 2 else np.full(2, math.nan)
    return {
        "method": spectrum.method,
        "exponents_per_s": spectrum.exponents_per_s.tolist(),
        "exponents_per_period": spectrum.exponents_per_period.tolist(),
        "period_s": spectrum.period_s,
        "interval_s": spectrum.interval_s,
        "intervals": n,
        "from_s": float(spectrum.t[0]),
        "to_s": float(spectrum.t[-1]),
        "standard_error_per_period": None if errors is None else errors.tolist(),
        "batches": CONVERGENCE_BATCHES if errors is not None else None,
        "change_over_last_half_per_period": [float(x) for x in change],
    }


def spectrum_text(report: dict[str, Any], period_name: str = "drive period") -> str:
    """:func:`spectrum_report`'s values as two lines for a terminal."""
    per_period = ", ".join(f"{x:+.4g}" for x in report["exponents_per_period"])
    per_s = ", ".join(f"{x:+.4g}" for x in report["exponents_per_s"])
    errors = report["standard_error_per_period"]
    settled = (f"batch-means standard error {', '.join(f'{x:.2g}' for x in errors)} per "
               f"{period_name} ({report['batches']} batches)" if errors is not None else
               f"too short for batch means (fewer than {2 * CONVERGENCE_BATCHES} intervals)")
    moved = ", ".join(f"{x:.2g}" for x in report["change_over_last_half_per_period"])
    return (f"Lyapunov spectrum ({report['method']}): {per_period} per {period_name} "
            f"({per_s} per s), over t = {report['from_s']:.6g} to {report['to_s']:.6g} s "
            f"({report['intervals']} intervals of {report['interval_s']:.6g} s)\n"
            f"  convergence: {settled}; the running averages moved {moved} per "
            f"{period_name} over the second half")


def _qr_2x2(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Q (orthonormal) and log of R's diagonal (positive) of a 2 x 2 matrix, Q R = matrix.

    R's second diagonal entry is det / R11, not a difference of nearly parallel columns:
    exact however strongly the flow has turned both columns toward one direction.
    """
    first = matrix[:, 0]
    r11 = math.hypot(first[0], first[1])
    det = matrix[0, 0] * matrix[1, 1] - matrix[0, 1] * matrix[1, 0]
    q1 = first / r11
    q2 = math.copysign(1.0, det) * np.array([-q1[1], q1[0]])
    return np.column_stack([q1, q2]), np.array([math.log(r11), math.log(abs(det)) - math.log(r11)])


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
