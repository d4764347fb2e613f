"""Fit the baseline model, or the baseline extended by one named cause, to a measured angle record.

One general mechanism for every cause of the registry: a cause's parameters join
the baseline's free parameters, dynamics causes act through the packed vector of
the compiled equations (``Model.with_extension``), measurement causes on the
simulated angle.  Each trial simulates the whole record (``simulate_packed`` at a
modest tolerance); the Jacobian is a forward difference with steps sized to each
parameter, and intervals come from the autocorrelation-consistent sandwich that
``analysis.identify`` uses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from analysis import quantities as q
from analysis.discrepancy.candidates import plan_for
from analysis.extensions import (
    ModelSpec,
    ParameterPlan,
    RecordScale,
    cause,
    coordinate_matrix,
)
from analysis.identify.intervals import Z95, sandwich_covariance
from analysis.identify.result import Estimate, Residuals, SampledRecord
from analysis.model import Drive, Model, RigParameters
from analysis.model_values import measured_angle, model_from_values, packed_from_values
from analysis.simulate import SimulationResult, SimulationSettings, simulate_packed

RTOL = 1e-8
ATOL = 1e-10
MAX_ITERATIONS = 25
START_INSIDE = 10.0  # steps between a start value and a bound

# the baseline parameters a decay fit adjusts; the contact's only with the barrier in
SWING_PARAMETERS = (q.theta0_rad, q.theta_dot0_rad_s, q.omega_rad_s, q.zeta)
CONTACT_PARAMETERS = (q.K_N_per_m1_5, q.mu0_s_per_m)
POSITIVE = {q.omega_rad_s, q.K_N_per_m1_5}  # fitted on a log scale
BOUNDS = {
    q.theta0_rad: (-math.pi, math.pi),  # large free swings start beyond the horizontal
    q.theta_dot0_rad_s: (-math.inf, math.inf),
    q.omega_rad_s: (0.0, math.inf),
    q.zeta: (0.0, 0.5),
    q.K_N_per_m1_5: (1e-3, 1e14),
    q.mu0_s_per_m: (0.0, 50.0),
}


@dataclass(frozen=True)
class FitData(SampledRecord):
    """The part of a record a fit uses: uniform times from 0, angle (NaN where excluded)."""

    experiment: str
    t: np.ndarray
    y: np.ndarray
    valid: np.ndarray
    noise_rad: float
    rig: RigParameters  # known constants (m, l, R, g); L, zeta, K, mu0 are fitted
    drive: Drive = field(default_factory=Drive)
    barrier: bool = False
    phase0_rad: float = 0.0

    def head(self, fraction: float) -> FitData:
        """The first ``fraction`` of the record (for held-out prediction of the rest)."""
        n = max(16, round(fraction * self.t.size))
        return replace(self, t=self.t[:n], y=self.y[:n], valid=self.valid[:n])


@dataclass(frozen=True)
class FitResult(Residuals):
    """A fitted model: its values, estimates with 95 % intervals, and residuals."""

    model: ModelSpec
    values: dict[str, float]
    estimates: dict[str, Estimate]
    residual: np.ndarray  # model - data over the whole FitData, NaN where not valid
    n_params: int
    success: bool
    message: str
    contacts: int = 0


def build_model(data: FitData, model: ModelSpec, values: Mapping[str, float]) -> Model:
    """The model ``model`` at the given values."""
    return model_from_values(data.rig, data.drive, data.barrier, values, model.causes)


def predict(
    data: FitData, model: ModelSpec, values: Mapping[str, float], n: int | None = None
) -> tuple[np.ndarray, SimulationResult]:
    """The angle the sensor would report under the model, at the record's sample times."""
    n = data.t.size if n is None else n
    p = packed_from_values(data.rig, data.drive, data.barrier, values, model.causes,
                           data.phase0_rad)
    sim = simulate_packed(
        p, values[q.theta0_rad], values[q.theta_dot0_rad_s],
        settings=SimulationSettings(
            duration_s=n * data.dt, fs_hz=1.0 / data.dt, poincare_phase=None, rtol=RTOL, atol=ATOL,
        ),
    )
    theta = np.asarray(sim.theta, dtype=float)[:n]
    if theta.size < n:
        # The trial left the experiment's regime: hold the last angle, so the optimiser sees
        # a large residual and steps back instead of failing.
        last = theta[-1] if theta.size else values[q.theta0_rad]
        theta = np.concatenate([theta, np.full(n - theta.size, last)])
    return measured_angle(model.causes, values, np.arange(n) * data.dt, theta), sim


def free_parameters(
    data: FitData, model: ModelSpec, scale: RecordScale, start: Mapping[str, float]
) -> dict[str, tuple[float, ParameterPlan, float, float]]:
    """name -> (start value, plan, lower, upper) of every parameter the fit adjusts."""
    causes = [cause(name) for name in model.causes]
    replaced = {name for c in causes for name in c.replaces}
    out: dict[str, tuple[float, ParameterPlan, float, float]] = {}
    for name in SWING_PARAMETERS + (CONTACT_PARAMETERS if data.barrier else ()):
        if name in replaced:
            continue
        value = start[name]
        log = name in POSITIVE
        out[name] = (value, ParameterPlan(value, _baseline_step(name, scale), log), *BOUNDS[name])
    for c in causes:
        plans = plan_for(c, scale)
        for spec in c.parameters:
            plan = plans[spec.name]
            value = start.get(spec.name, plan.start)
            value = min(max(value, spec.lower), spec.upper)
            out[spec.name] = (value, plan, spec.lower, spec.upper)
    return out


def _baseline_step(name: str, s: RecordScale) -> float:
    steps = {
        q.theta0_rad: 1e-6 * max(s.amplitude_rad, 1e-2),
        q.theta_dot0_rad_s: 1e-6 * s.omega_rad_s * max(s.amplitude_rad, 1e-2),
        q.omega_rad_s: 1e-7,  # log scale: relative step
        q.zeta: 1e-4 * max(s.zeta, 1e-4),
        q.K_N_per_m1_5: 1e-4,  # log scale
        q.mu0_s_per_m: 1e-4 * max(s.mu0_s_per_m, 1e-2),
    }
    return steps[name]


def fit(
    data: FitData,
    model: ModelSpec,
    start: Mapping[str, float],
    scale: RecordScale,
    *,
    max_iterations: int = MAX_ITERATIONS,
) -> FitResult:
    """Least-squares fit of model ``model`` (the baseline, or the baseline extended by one
    cause or several)."""
    free = free_parameters(data, model, scale, start)
    names = list(free)
    fixed = {k: v for k, v in start.items() if k not in free}
    # Work in step units u: x = x0 + u * step (or log x = log x0 + u * step), so a unit
    # change of u is a well-resolved change of the model for every parameter.
    origin = np.array([math.log(max(free[k][0], 1e-300)) if free[k][1].log else free[k][0]
                       for k in names])
    steps = np.array([free[k][1].step for k in names])
    coordinates = coordinate_matrix(names, steps, [free[k][1].tie for k in names])
    lower = np.empty(len(names))
    upper = np.empty(len(names))
    for i, k in enumerate(names):
        _, plan, lo, hi = free[k]
        if plan.log:
            lo, hi = math.log(max(lo, 1e-300)), math.log(hi) if math.isfinite(hi) else math.inf
        lower[i] = (lo - origin[i]) / steps[i]
        upper[i] = (hi - origin[i]) / steps[i]
    logs = np.array([free[k][1].log for k in names])
    mask = data.valid
    y = data.y[mask]

    tied = np.array([free[k][1].tie is not None for k in names])
    low = np.array([free[k][2] for k in names])
    high = np.array([free[k][3] for k in names])

    def values_of(u: np.ndarray) -> dict[str, float]:
        raw = origin + coordinates @ u
        raw = np.where(logs, np.exp(np.where(logs, raw, 0.0)), raw)
        # a tied parameter's box in step units holds at its partner's start only
        raw = np.where(tied, np.clip(raw, low, high), raw)
        return {**fixed, **dict(zip(names, raw.tolist(), strict=True))}

    def residual(u: np.ndarray) -> np.ndarray:
        theta, _ = predict(data, model, values_of(u))
        return theta[mask] - y

    def jacobian(u: np.ndarray) -> np.ndarray:
        r0 = residual(u)
        jac = np.empty((r0.size, u.size))
        for i in range(u.size):
            h = 1.0 if u[i] + 1.0 <= upper[i] else -1.0
            du = u.copy()
            du[i] += h
            jac[:, i] = (residual(du) - r0) / h
        return jac

    # A start on a bound stalls the trust-region reflective method (its scaling there is 0):
    # start a few steps inside, which leaves the model as good as unchanged.
    u0 = np.clip(np.zeros(len(names)), lower + START_INSIDE, upper - START_INSIDE)
    narrow = (upper - lower) <= 2 * START_INSIDE  # only finite bounds can be this close
    u0[narrow] = 0.5 * (lower[narrow] + upper[narrow])
    solution = least_squares(
        residual, u0, jac=jacobian, bounds=(lower, upper), method="trf", x_scale="jac",
        max_nfev=max_iterations, xtol=1e-10, ftol=1e-10,
    )
    values = values_of(solution.x)
    theta, sim = predict(data, model, values)
    full_residual = np.where(mask, theta - np.where(mask, data.y, 0.0), np.nan)
    estimates = _estimates(names, solution, values, coordinates, logs)
    return FitResult(
        model=model, values=values, estimates=estimates, residual=full_residual,
        n_params=len(names), success=bool(solution.status > 0), message=str(solution.message),
        contacts=sim.contacts.count,
    )


def _estimates(names, solution, values, coordinates, logs) -> dict[str, Estimate]:
    """95 % intervals from the sandwich covariance at the solution (delta method to x)."""
    out: dict[str, Estimate] = {}
    try:
        cov = sandwich_covariance([(solution.fun, solution.jac)])
        variances = np.einsum("ij,jk,ik->i", coordinates, cov.matrix, coordinates)
    except (np.linalg.LinAlgError, ValueError):
        variances = np.full(len(names), np.nan)
    for i, k in enumerate(names):
        value = values[k]
        half = Z95 * math.sqrt(variances[i]) if variances[i] >= 0 else math.nan
        if not math.isfinite(half) or (logs[i] and half > 50.0):
            out[k] = Estimate(value)  # not identified: no honest interval
        elif logs[i]:
            out[k] = Estimate(value, (value * math.exp(-half), value * math.exp(half)))
        else:
            out[k] = Estimate(value, (value - half, value + half))
    return out
