"""Impact decay (barrier present, no drive): contact stiffness K (hence E given R) and mu0.

A fast first estimate comes from the impacts themselves: the free flight between
impacts (fitted as a sinusoid about the sensor zero) gives, at the barrier angle,
the entry and exit speeds and the contact time; restitution e = 1 - (2/3) mu0 v
gives mu0 and t_c = 3.2181 (m_eff^2 / (K^2 v))^(1/5) gives K (docs/MODEL.md section 4).
The final estimate simulates the whole record with the project's simulator and
fits it by least squares; L and zeta are held when known from a free decay.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy.optimize import minimize_scalar

from analysis import quantities as q
from analysis.experiments import FREE_DECAY
from analysis.identify.free_decay import SIMULATION_DIFF_STEP, _robust_fit, fit_free_decay
from analysis.identify.preprocess import PreparedSignal, prepare
from analysis.identify.result import Estimate, IdentificationError, IdentificationResult
from analysis.identify.threads import blas_on_one_thread
from analysis.model import Drive, Model, RigParameters
from analysis.records import Record

CONTACT_TIME_CONSTANT = 3.2181
FITTED = (q.L_m, q.zeta)
FREE_SWING_RATIO = 3.0  # a barrier-free fit this close to the noise means no impacts
MIN_SHORTFALL = 0.03  # impacts must stop the swing this fraction below its free height
TROUGH_SPAN, TROUGH_DEGREE = 0.2, 6


def _segments(
    angle: np.ndarray, level: float, hysteresis: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of the runs above ``level``; a run ends only below level - hysteresis.

    Without hysteresis, noise at the level would split one excursion into many.
    """
    state = np.zeros(angle.size, dtype=np.int8)
    state[angle > level] = 1
    state[angle < level - hysteresis] = -1
    marks = np.where(state != 0, np.arange(angle.size), 0)
    np.maximum.accumulate(marks, out=marks)
    held = np.where(marks > 0, state[marks], state[0])
    held[0] = 1 if state[0] == 1 else -1 if held[0] == 0 else held[0]
    above = np.concatenate([[False], held == 1, [False]])
    edges = np.flatnonzero(above[1:] != above[:-1])
    return edges[0::2], edges[1::2]


def impact_events(
    signal: PreparedSignal, rig: RigParameters, omega_hint: float | None = None
) -> dict[str, np.ndarray | float]:
    """First estimates from the impacts: omega, sensor offset, theta_b, K, mu0 (see module doc).

    omega and the sensor zero come from the curvature at the lower turning points
    (there theta' = 0, so theta'' = -omega^2 sin(theta - offset) whatever the damping);
    the free flight between impacts is then a sinusoid about that zero, and theta_b
    is the barrier angle at which the contact times and entry speeds predict the
    observed peak penetrations (t_c and delta_max of the Hertz impact, docs/MODEL.md).
    """
    t = signal.time_s
    good = signal.valid
    theta = np.where(good, signal.angle_rad, np.nan)
    idx = np.arange(t.size)
    filled = np.interp(idx, idx[good], theta[good])
    high = np.percentile(filled, 99.5)
    low = np.percentile(filled, 0.5)
    cstarts, cstops = _contact_runs(filled, high, low, 6.0 * signal.noise_rad)
    depth_a, curvature_a = _lower_turning_points(t, good, filled, cstarts, cstops)
    omega, offset = _frequency_and_zero(depth_a, curvature_a, high, omega_hint)
    # Free flights between contacts, each a sinusoid about the sensor zero.
    pieces = [(cstops[k], cstarts[k + 1]) for k in range(cstarts.size - 1)]
    arcs = []
    for a, b in pieces:
        m = good[a:b]
        basis = np.column_stack([np.cos(omega * t[a:b]), np.sin(omega * t[a:b])])
        (ca, cb), *_ = np.linalg.lstsq(basis[m], filled[a:b][m] - offset, rcond=None)
        arcs.append((math.hypot(ca, cb), math.atan2(cb, ca), t[b - 1]))
    peaks = np.array([filled[pieces[k][1]:pieces[k + 1][0]].max() for k in range(len(arcs) - 1)])
    reach = np.array([offset + arcs[k][0] for k in range(len(arcs) - 1)])
    shortfall = (reach - peaks) / np.maximum(reach - offset, 1e-12)
    if np.median(shortfall) < MIN_SHORTFALL:
        raise IdentificationError(
            "no impacts found: the swings reach the height of free flight (median shortfall "
            f"{100 * np.median(shortfall):.2g} % of the amplitude); is the barrier in place?"
        )
    shaft = rig.l_m
    m_eff = rig.m_kg * (rig.g_m_s2 / omega**2) ** 2 / shaft**2

    def impacts(theta_b: float) -> tuple[np.ndarray, ...]:
        rows = []
        for k in range(len(arcs) - 1):
            (amp1, ph1, near), (amp2, ph2, _) = arcs[k], arcs[k + 1]
            if amp1 <= abs(theta_b) or amp2 <= abs(theta_b):
                continue
            enter = _crossing_time(amp1, ph1, omega, theta_b, near, rising=True)
            leave = _crossing_time(amp2, ph2, omega, theta_b, near, rising=False)
            if leave <= enter:
                continue
            rows.append((omega * math.sqrt(amp1**2 - theta_b**2),
                         omega * math.sqrt(amp2**2 - theta_b**2), leave - enter, peaks[k]))
        return tuple(np.array(col) for col in zip(*rows, strict=True)) if rows else ()

    def mismatch(theta_b: float) -> float:
        found = impacts(theta_b)
        if not found or found[0].size < 2:
            return math.inf
        w_in, _, t_c, top = found
        v = shaft * w_in
        K_each = np.sqrt(m_eff**2 / v * (CONTACT_TIME_CONSTANT / t_c) ** 5)
        reach_in = (5.0 * m_eff * v**2 / (4.0 * K_each)) ** 0.4 / shaft
        return float(np.sum((offset + theta_b + reach_in - top) ** 2))

    upper = float(np.median(peaks)) - offset
    lower = upper - 0.5 * (upper - float(np.median(depth_a)) + offset)
    grid = np.linspace(lower, upper, 81)
    costs = np.array([mismatch(b) for b in grid])
    if not np.any(np.isfinite(costs)):
        raise IdentificationError("no impacts found: contact times could not be measured")
    best = int(np.nanargmin(costs))
    refined = minimize_scalar(
        mismatch, bounds=(grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]),
        method="bounded",
    )
    theta_b = float(refined.x) if refined.fun <= costs[best] else float(grid[best])
    w_in, w_out, t_c, _ = impacts(theta_b)
    v = shaft * w_in
    K = float(np.median(np.sqrt(m_eff**2 / v * (CONTACT_TIME_CONSTANT / t_c) ** 5)))
    restitution = w_out / w_in
    mu0 = float(1.5 * np.sum((1.0 - restitution) * v) / np.sum(v * v))
    return {
        q.omega_rad_s: omega, q.offset_rad: offset, q.theta_b_rad: theta_b, "K": K,
        "mu0": max(mu0, 0.0), "v_in": w_in, "restitution": restitution, "t_c": t_c,
    }


def _contact_runs(
    filled: np.ndarray, high: float, low: float, hysteresis: float
) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of the upper excursions that reach the barrier."""
    starts, stops = _segments(filled, high - 0.15 * (high - low), hysteresis)
    peaks_all = np.array([filled[a:b].max() for a, b in zip(starts, stops, strict=True)])
    if peaks_all.size < 3:
        raise IdentificationError(
            f"no impacts found: only {peaks_all.size} excursion(s) reach the upper level; an "
            "impact-decay record needs at least 3 impacts"
        )
    guard = 0.08 * (high - low)
    cstarts, cstops = _segments(filled, np.median(peaks_all) - guard, hysteresis)
    if cstarts.size < 4:
        raise IdentificationError(
            f"no impacts found: only {cstarts.size} upper excursions; need at least 4"
        )
    return cstarts, cstops


def _lower_turning_points(
    t: np.ndarray, good: np.ndarray, filled: np.ndarray, cstarts: np.ndarray, cstops: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Depth and curvature of the lower turning points between successive upper excursions."""
    troughs = np.array([
        cstops[k] + int(np.argmin(filled[cstops[k]:cstarts[k + 1]]))
        for k in range(cstarts.size - 1)
    ])
    spacing = float(np.median(np.diff(troughs))) if troughs.size > 1 else 0.0
    half = max(4, int(TROUGH_SPAN * spacing))
    depth, curvature = [], []
    for i in troughs:
        if i - half < 0 or i + half >= t.size:
            continue
        window = slice(i - half, i + half + 1)
        tau = t[window] - t[i]
        coeffs = np.polyfit(tau[good[window]], filled[window][good[window]], TROUGH_DEGREE)
        depth.append(filled[i])
        curvature.append(2.0 * coeffs[-3])
    return np.array(depth), np.array(curvature)


def _frequency_and_zero(
    depth_a: np.ndarray, curvature_a: np.ndarray, high: float, omega_hint: float | None
) -> tuple[float, float]:
    """omega and the sensor zero from theta'' = -omega^2 sin(theta - offset) at the turning
    points; a held omega (``omega_hint``) is exact and only the zero is solved for."""
    if depth_a.size >= 3 and np.ptp(depth_a) > 0.1 * np.median(np.abs(depth_a - high)):
        slope, intercept = np.polyfit(depth_a, curvature_a, 1)  # curv = -w^2 (depth - c)
        omega = math.sqrt(max(-slope, 1e-12))
        offset = intercept / omega**2
    elif omega_hint:
        omega = omega_hint
        offset = float(np.median(depth_a + curvature_a / omega**2))
    else:
        raise IdentificationError(
            "cannot separate frequency and sensor zero: the lower turning points hardly "
            "change depth; hold L_m (--hold or --free-decay)"
        )
    if omega_hint:  # a held length is exact; the curvature estimate is not
        omega = omega_hint
        # theta'' = -omega^2 sin(depth - offset) at a turning point, solved for the offset
        offset = float(np.median(depth_a + np.arcsin(np.clip(curvature_a / omega**2, -1, 1))))
    return omega, offset


def _crossing_time(amp: float, phase: float, w: float, level: float, near: float,
                   rising: bool) -> float:
    """Time nearest ``near`` where amp cos(w t - phase) = level while rising (or falling)."""
    base = math.acos(max(-1.0, min(1.0, level / amp)))
    # cos(x) = level at x = +-base; rising where sin(x) < 0, i.e. x = -base (mod 2 pi).
    x = -base if rising else base
    k = round((w * near - phase - x) / (2 * math.pi))
    return (x + phase + 2 * math.pi * k) / w


def fit_impact_decay(
    record: Record,
    *,
    hold: Mapping[str, float] | None = None,
    detect_release: bool = True,
) -> IdentificationResult:
    """Identify K (E for the record's R), mu0, theta_b, initial state; L, zeta held or fitted."""
    blas_on_one_thread()
    hold = dict(hold or {})
    unknown = sorted(set(hold) - set(FITTED))
    if unknown:
        raise ValueError(f"cannot hold {unknown}; holdable: {FITTED}")
    if q.L_m in hold and not (math.isfinite(hold[q.L_m]) and hold[q.L_m] > 0):
        raise ValueError(f"held L_m = {hold[q.L_m]!r}: must be a positive length in m")
    if q.zeta in hold and not (math.isfinite(hold[q.zeta]) and 0 <= hold[q.zeta] < 1):
        raise ValueError(f"held zeta = {hold[q.zeta]!r}: must lie in [0, 1)")
    rig0 = record.rig_parameters()
    g = record.gravity_m_s2
    signal = prepare(record.time_s, record.angle_rad, detect_release=detect_release)
    _refuse_free_decay(record, signal)
    omega_hint = math.sqrt(g / hold[q.L_m]) if q.L_m in hold else None
    events = impact_events(signal, rig0.with_values(g_m_s2=g), omega_hint)
    omega0 = float(events[q.omega_rad_s])
    zeta0 = hold.get(q.zeta, 0.005)
    theta_start = float(signal.angle_rad[signal.valid][0]) - events[q.offset_rad]
    dt = float(signal.time_s[1] - signal.time_s[0])
    theta_dot_start = float(
        np.polyfit(signal.time_s[:5], np.nan_to_num(signal.angle_rad[:5], nan=theta_start), 1)[0]
    )
    names = [q.theta0_rad, q.theta_dot0_rad_s, "log_K", q.mu0_s_per_m, q.theta_b_rad,
             q.offset_rad]
    x0 = [theta_start, theta_dot_start, math.log(events["K"]), events["mu0"],
          events[q.theta_b_rad], events[q.offset_rad]]
    lower = [-math.pi / 2, -math.inf, math.log(events["K"]) - 5, 0.0, -1.0, -math.inf]
    upper = [math.pi / 2, math.inf, math.log(events["K"]) + 5, 50.0, 1.0, math.inf]
    if q.L_m not in hold:
        names.append(q.omega_rad_s)
        x0.append(omega0)
        lower.append(0.7 * omega0)
        upper.append(1.3 * omega0)
    if q.zeta not in hold:
        names.append(q.zeta)
        x0.append(zeta0)
        lower.append(0.0)
        upper.append(0.5)

    def curve(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        values = dict(zip(names, x, strict=True))
        omega = values.get(q.omega_rad_s, omega0)
        rig = rig0.with_values(
            L_m=g / omega**2, g_m_s2=g, zeta=values.get(q.zeta, zeta0),
            mu0_s_per_m=values[q.mu0_s_per_m], theta_b_rad=values[q.theta_b_rad],
        ).with_stiffness(math.exp(values["log_K"]))
        return _simulate(rig, values[q.theta0_rad], values[q.theta_dot0_rad_s], dt, t.size) \
            + values[q.offset_rad]

    x, cov, quality, excluded = _robust_fit(
        signal, curve, x0, lower, upper, 2.0 * math.pi / omega0, diff_step=SIMULATION_DIFF_STEP
    )
    values = dict(zip(names, x, strict=True))
    i_k = names.index("log_K")
    K = math.exp(values["log_K"])
    lo, hi = cov.ci95(values["log_K"], i_k)
    R = rig0.R_m
    parameters = {
        q.K_N_per_m1_5: Estimate(K, (math.exp(lo), math.exp(hi))),
        q.E_Pa: Estimate(*_e_from_k(K, math.exp(lo), math.exp(hi), R)),
        q.R_m: Estimate(R),
        q.mu0_s_per_m: Estimate(values[q.mu0_s_per_m], cov.ci95(values[q.mu0_s_per_m],
                                                                names.index(q.mu0_s_per_m))),
        q.theta_b_rad: Estimate(values[q.theta_b_rad], cov.ci95(values[q.theta_b_rad],
                                                                names.index(q.theta_b_rad))),
        q.theta0_rad: Estimate(values[q.theta0_rad], cov.ci95(values[q.theta0_rad], 0)),
        q.offset_rad: Estimate(values[q.offset_rad], cov.ci95(values[q.offset_rad],
                                                              names.index(q.offset_rad))),
    }
    if q.omega_rad_s in values:
        i = names.index(q.omega_rad_s)
        omega = values[q.omega_rad_s]
        grad = np.zeros(len(names))
        grad[i] = -2.0 * g / omega**3
        parameters[q.L_m] = Estimate(g / omega**2, cov.derived_ci95(g / omega**2, grad))
        parameters[q.omega_rad_s] = Estimate(omega, cov.ci95(omega, i))
    else:
        parameters[q.L_m] = Estimate(hold[q.L_m])
    if q.zeta in values:
        parameters[q.zeta] = Estimate(values[q.zeta], cov.ci95(values[q.zeta],
                                                               names.index(q.zeta)))
    else:
        parameters[q.zeta] = Estimate(hold[q.zeta])
    warnings = []
    if signal.n_nonfinite or signal.n_spikes:
        warnings.append(
            f"excluded {signal.n_nonfinite} non-finite and {signal.n_spikes} spike sample(s)"
        )
    if quality.rms_residual_rad > 3.0 * quality.noise_rad:
        warnings.append(
            f"poor fit: residual rms {quality.rms_residual_rad:.3g} rad is "
            f"{quality.rms_residual_rad / max(quality.noise_rad, 1e-300):.3g} x the sample noise"
        )
    details = {
        "fit_model": "full simulation with barrier",
        "held": hold,
        "release_trim_s": signal.trim_start_s,
        "rest_trim_s": signal.trim_end_s,
        "outlier_samples": excluded,
        "impacts_used_for_first_estimate": int(events["v_in"].size),
        "first_estimate": {
            q.K_N_per_m1_5: float(events["K"]), q.mu0_s_per_m: float(events["mu0"]),
            q.theta_b_rad: float(events[q.theta_b_rad]),
        },
        "fitted": {k: float(v) for k, v in values.items()},
        q.m_kg: rig0.m_kg, q.l_m: rig0.l_m,
    }
    return IdentificationResult(
        experiment=record.experiment, method="impact decay, full simulation",
        parameters=parameters, quality=quality, warnings=tuple(warnings), details=details,
    )


def _refuse_free_decay(record: Record, signal: PreparedSignal) -> None:
    """Raise when the start of the record is explained by a free swing: no impacts happened."""
    fs = record.sample_rate_hz
    head = slice(signal.start_index, min(signal.stop_index, signal.start_index + int(3.0 * fs)))
    probe = Record(record.time_s[head], record.angle_rad[head], FREE_DECAY.name, rig=record.rig)
    try:
        free = fit_free_decay(probe, detect_release=False)
    except IdentificationError:
        return  # not even a free swing fits: not the reason to refuse
    ratio = free.quality.rms_residual_rad / max(free.quality.noise_rad, 1e-300)
    if ratio < FREE_SWING_RATIO:
        raise IdentificationError(
            "no impacts found: the record is a free swing (a fit without barrier leaves "
            f"residuals of {ratio:.2g} x the noise); is the barrier in place?"
        )


def _e_from_k(K: float, lo: float, hi: float, R: float) -> tuple[float, tuple[float, float]]:
    factor = 3.0 / (4.0 * math.sqrt(R))
    return K * factor, (lo * factor, hi * factor)


def _simulate(rig: RigParameters, theta0: float, theta_dot0: float, dt: float, n: int):
    from analysis.simulate import SimulationSettings, simulate

    result = simulate(
        Model(rig=rig, drive=Drive(), barrier=True), theta0, theta_dot0,
        settings=SimulationSettings(
            duration_s=n * dt, fs_hz=1.0 / dt, poincare_phase=None, rtol=1e-9, atol=1e-11,
        ),
    )
    theta = np.asarray(result.theta, dtype=float)[:n]
    if theta.size < n:
        last = theta[-1] if theta.size else theta0
        theta = np.concatenate([theta, np.full(n - theta.size, last)])
    return theta


__all__ = ["fit_impact_decay", "impact_events"]
