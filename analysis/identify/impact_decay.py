"""Impact decay (barrier present, no drive): contact stiffness K (hence E given R) and mu0.

A fast first estimate comes from the impacts themselves: the free flight between
impacts (fitted as a sinusoid about the sensor zero) gives, at the barrier angle,
the entry and exit speeds and the contact time; restitution e = 1 - (2/3) mu0 v
gives mu0 and t_c = 3.2181 (m_eff^2 / (K^2 v))^(1/5) gives K (MODEL.md section 4).
The final estimate simulates the whole record with the project's simulator and
fits it by least squares; L and zeta are held when known from a free decay.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy.optimize import minimize_scalar

from analysis.identify.free_decay import _robust_fit
from analysis.identify.preprocess import PreparedSignal, prepare
from analysis.identify.result import Estimate, IdentificationError, IdentificationResult
from analysis.model import Drive, Model, RigParameters
from analysis.records import Record

CONTACT_TIME_CONSTANT = 3.2181
FITTED = ("L_m", "zeta")
MIN_SHORTFALL = 0.03  # impacts must stop the swing this fraction below its free height


def _segments(angle: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of the runs where angle > level (contact candidates)."""
    above = np.concatenate([[False], angle > level, [False]])
    edges = np.flatnonzero(above[1:] != above[:-1])
    return edges[0::2], edges[1::2]


def impact_events(
    signal: PreparedSignal, omega: float, rig: RigParameters
) -> dict[str, np.ndarray | float]:
    """Per-impact entry/exit speeds and contact times from the free flight around each impact."""
    t = signal.time_s
    good = signal.valid
    theta = np.where(good, signal.angle_rad, np.nan)
    idx = np.arange(t.size)
    filled = np.interp(idx, idx[good], theta[good])
    high = np.percentile(filled, 99.5)
    low = np.percentile(filled, 0.5)
    starts, stops = _segments(filled, high - 0.15 * (high - low))
    peaks = np.array([filled[a:b].max() for a, b in zip(starts, stops, strict=True)])
    if peaks.size < 3:
        raise IdentificationError(
            f"no impacts found: only {peaks.size} excursion(s) reach the upper level; an "
            "impact-decay record needs at least 3 impacts"
        )
    guard = 0.08 * (high - low)
    cstarts, cstops = _segments(filled, np.median(peaks) - guard)
    # Free-flight segments between successive contacts; each is c + a cos(w t) + b sin(w t).
    pieces = [(cstops[k], cstarts[k + 1]) for k in range(cstarts.size - 1)]
    pieces = [(a, b) for a, b in pieces if b - a > 8]
    if len(pieces) < 2:
        raise IdentificationError("no impacts found: too few free flights between contacts")

    def segment_fit(w: float) -> tuple[float, list[np.ndarray], float]:
        rows, rhs, blocks = [], [], []
        for k, (a, b) in enumerate(pieces):
            tt = t[a:b]
            m = good[a:b]
            basis = np.zeros((tt.size, 1 + 2 * len(pieces)))
            basis[:, 0] = 1.0
            basis[:, 1 + 2 * k] = np.cos(w * tt)
            basis[:, 2 + 2 * k] = np.sin(w * tt)
            rows.append(basis[m])
            rhs.append(filled[a:b][m])
            blocks.append(k)
        A = np.vstack(rows)
        y = np.concatenate(rhs)
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        cost = float(np.sum((A @ coef - y) ** 2))
        return cost, coef, 0.0

    found = minimize_scalar(
        lambda w: segment_fit(w)[0], bounds=(0.6 * omega, 1.5 * omega), method="bounded"
    )
    w = float(found.x)
    _, coef, _ = segment_fit(w)
    offset = float(coef[0])
    # A barrier stops the swing short of the height the free flight before it would reach;
    # without impacts the upper turning points sit on the free-flight sinusoid.
    shortfall = []
    for k in range(len(pieces) - 1):
        reach = offset + math.hypot(coef[1 + 2 * k], coef[2 + 2 * k])
        top = filled[pieces[k][1]:pieces[k + 1][0]].max()
        shortfall.append((reach - top) / max(reach - offset, 1e-12))
    if np.median(shortfall) < MIN_SHORTFALL:
        raise IdentificationError(
            "no impacts found: the swings reach the height of free flight (median shortfall "
            f"{100 * np.median(shortfall):.2g} % of the amplitude); is the barrier in place?"
        )
    L = rig.l_m
    m_eff = rig.m_kg * rig.L_m**2 / rig.l_m**2
    theta_b = float(np.median(peaks)) - offset
    K = rig.K_N_per_m1_5
    for _ in range(3):
        v_in, v_out, t_c = [], [], []
        for k in range(len(pieces) - 1):
            a1, b1 = coef[1 + 2 * k], coef[2 + 2 * k]
            a2, b2 = coef[3 + 2 * k], coef[4 + 2 * k]
            amp1, amp2 = math.hypot(a1, b1), math.hypot(a2, b2)
            if amp1 <= abs(theta_b) or amp2 <= abs(theta_b):
                continue
            # Segment k rises to theta_b, segment k+1 leaves it: times on each sinusoid.
            ph1, ph2 = math.atan2(b1, a1), math.atan2(b2, a2)
            contact_t = t[pieces[k][1]]
            enter = _crossing_time(amp1, ph1, w, theta_b, contact_t, rising=True)
            leave = _crossing_time(amp2, ph2, w, theta_b, contact_t, rising=False)
            speed_in = w * math.sqrt(amp1**2 - theta_b**2)
            speed_out = w * math.sqrt(amp2**2 - theta_b**2)
            if leave > enter:
                v_in.append(speed_in)
                v_out.append(speed_out)
                t_c.append(leave - enter)
        if len(v_in) < 2:
            raise IdentificationError("no impacts found: contact times could not be measured")
        v_in_a, v_out_a, t_c_a = np.array(v_in), np.array(v_out), np.array(t_c)
        v = L * v_in_a  # contact-point speed l theta'_in
        K_each = np.sqrt(m_eff**2 / v * (CONTACT_TIME_CONSTANT / t_c_a) ** 5)
        K = float(np.median(K_each))
        penetration = (5.0 * m_eff * np.median(v) ** 2 / (4.0 * K)) ** 0.4
        theta_b = float(np.median(peaks)) - offset - penetration / L
    restitution = v_out_a / v_in_a
    mu0 = float(1.5 * np.sum((1.0 - restitution) * v) / np.sum(v * v))
    return {
        "omega_rad_s": w, "offset_rad": offset, "theta_b_rad": theta_b, "K": K,
        "mu0": max(mu0, 0.0), "v_in": v_in_a, "restitution": restitution, "t_c": t_c_a,
    }


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
    hold = dict(hold or {})
    unknown = sorted(set(hold) - set(FITTED))
    if unknown:
        raise ValueError(f"cannot hold {unknown}; holdable: {FITTED}")
    rig0 = record.rig_parameters()
    g = record.gravity_m_s2
    signal = prepare(record.time_s, record.angle_rad, detect_release=detect_release)
    L_guess = hold.get("L_m", rig0.L_m)
    omega_guess = math.sqrt(g / L_guess)
    if "L_m" not in hold:
        omega_guess = _dominant_omega(signal)
    events = impact_events(signal, omega_guess, rig0.with_values(L_m=g / omega_guess**2))
    omega0 = events["omega_rad_s"] if "L_m" not in hold else math.sqrt(g / hold["L_m"])
    zeta0 = hold.get("zeta", 0.005)
    theta_start = float(signal.angle_rad[signal.valid][0]) - events["offset_rad"]
    dt = float(signal.time_s[1] - signal.time_s[0])
    theta_dot_start = float(
        np.polyfit(signal.time_s[:5], np.nan_to_num(signal.angle_rad[:5], nan=theta_start), 1)[0]
    )
    names = ["theta0_rad", "theta_dot0_rad_s", "log_K", "mu0_s_per_m", "theta_b_rad",
             "offset_rad"]
    x0 = [theta_start, theta_dot_start, math.log(events["K"]), events["mu0"],
          events["theta_b_rad"], events["offset_rad"]]
    lower = [-math.pi / 2, -math.inf, math.log(events["K"]) - 5, 0.0, -1.0, -math.inf]
    upper = [math.pi / 2, math.inf, math.log(events["K"]) + 5, 50.0, 1.0, math.inf]
    if "L_m" not in hold:
        names.append("omega_rad_s")
        x0.append(omega0)
        lower.append(0.7 * omega0)
        upper.append(1.3 * omega0)
    if "zeta" not in hold:
        names.append("zeta")
        x0.append(zeta0)
        lower.append(0.0)
        upper.append(0.5)
    n_samples = signal.time_s.size

    def curve(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        values = dict(zip(names, x, strict=True))
        omega = values.get("omega_rad_s", omega0)
        rig = rig0.with_values(
            L_m=g / omega**2, g_m_s2=g, zeta=values.get("zeta", zeta0),
            mu0_s_per_m=values["mu0_s_per_m"], theta_b_rad=values["theta_b_rad"],
        ).with_stiffness(math.exp(values["log_K"]))
        return _simulate(rig, values["theta0_rad"], values["theta_dot0_rad_s"], dt, n_samples) \
            + values["offset_rad"]

    x, cov, quality, excluded = _robust_fit(
        signal, curve, x0, lower, upper, 2.0 * math.pi / omega0
    )
    values = dict(zip(names, x, strict=True))
    i_k = names.index("log_K")
    K = math.exp(values["log_K"])
    lo, hi = cov.ci95(values["log_K"], i_k)
    R = rig0.R_m
    parameters = {
        "K_N_per_m1.5": Estimate(K, (math.exp(lo), math.exp(hi))),
        "E_Pa": Estimate(*_e_from_k(K, math.exp(lo), math.exp(hi), R)),
        "R_m": Estimate(R),
        "mu0_s_per_m": Estimate(values["mu0_s_per_m"], cov.ci95(values["mu0_s_per_m"],
                                                                names.index("mu0_s_per_m"))),
        "theta_b_rad": Estimate(values["theta_b_rad"], cov.ci95(values["theta_b_rad"],
                                                                names.index("theta_b_rad"))),
        "theta0_rad": Estimate(values["theta0_rad"], cov.ci95(values["theta0_rad"], 0)),
        "offset_rad": Estimate(values["offset_rad"], cov.ci95(values["offset_rad"],
                                                              names.index("offset_rad"))),
    }
    if "omega_rad_s" in values:
        i = names.index("omega_rad_s")
        omega = values["omega_rad_s"]
        grad = np.zeros(len(names))
        grad[i] = -2.0 * g / omega**3
        parameters["L_m"] = Estimate(g / omega**2, cov.derived_ci95(g / omega**2, grad))
        parameters["omega_rad_s"] = Estimate(omega, cov.ci95(omega, i))
    else:
        parameters["L_m"] = Estimate(hold["L_m"])
    if "zeta" in values:
        parameters["zeta"] = Estimate(values["zeta"], cov.ci95(values["zeta"],
                                                               names.index("zeta")))
    else:
        parameters["zeta"] = Estimate(hold["zeta"])
    warnings = []
    if signal.n_nonfinite or signal.n_spikes:
        warnings.append(
            f"excluded {signal.n_nonfinite} non-finite and {signal.n_spikes} spike sample(s)"
        )
    if quality.rms_residual_rad > 3.0 * quality.noise_rad:
        warnings.append(
            f"poor fit: residual rms {quality.rms_residual_rad:.3g} rad is "
            f"{quality.rms_residual_rad / quality.noise_rad:.3g} x the sample noise"
        )
    details = {
        "fit_model": "full simulation with barrier",
        "held": hold,
        "release_trim_s": signal.trim_start_s,
        "rest_trim_s": signal.trim_end_s,
        "outlier_samples": excluded,
        "impacts_used_for_first_estimate": int(events["v_in"].size),
        "first_estimate": {
            "K_N_per_m1.5": float(events["K"]), "mu0_s_per_m": float(events["mu0"]),
            "theta_b_rad": float(events["theta_b_rad"]),
        },
        "fitted": {k: float(v) for k, v in values.items()},
        "m_kg": rig0.m_kg, "l_m": rig0.l_m,
    }
    return IdentificationResult(
        experiment=record.experiment, method="impact decay, full simulation",
        parameters=parameters, quality=quality, warnings=tuple(warnings), details=details,
    )


def _e_from_k(K: float, lo: float, hi: float, R: float) -> tuple[float, tuple[float, float]]:
    factor = 3.0 / (4.0 * math.sqrt(R))
    return K * factor, (lo * factor, hi * factor)


def _dominant_omega(signal: PreparedSignal) -> float:
    """Free-flight frequency from the time spent below half the trough depth.

    Impacts cut the upper half swing short, so the spectrum peak is not omega; the
    lower half swing is free: a sinusoid of amplitude A spends 2 acos(1/2) / omega
    = (2 pi / 3) / omega below -A/2.
    """
    good = signal.valid
    angle = signal.angle_rad[good]
    t = signal.time_s[good]
    low = np.percentile(angle, 1.0)
    high = np.percentile(angle, 99.0)
    centre = 0.5 * (low + high) if high < 0 else min(0.0, 0.5 * (low + high))
    level = centre - 0.5 * (centre - low) if high < 0 else 0.5 * low
    starts, stops = _segments(-angle, -level)
    durations = t[np.minimum(stops, t.size - 1)] - t[starts]
    durations = durations[(starts > 0) & (stops < t.size)]
    # Noise makes brief chatter segments at the level; the swings are the long ones.
    durations = durations[durations > 0.3 * durations.max()] if durations.size else durations
    if durations.size == 0:
        raise IdentificationError("no oscillation: the angle never swings below its rest level")
    return (2.0 * math.pi / 3.0) / float(np.median(durations))


def _simulate(rig: RigParameters, theta0: float, theta_dot0: float, dt: float, n: int):
    from analysis.simulate import simulate

    result = simulate(
        Model(rig=rig, drive=Drive(), barrier=True), theta0, theta_dot0,
        duration_s=n * dt, fs_hz=1.0 / dt, poincare_phase=None, rtol=1e-9, atol=1e-11,
    )
    theta = np.asarray(result.theta, dtype=float)[:n]
    if theta.size < n:
        last = theta[-1] if theta.size else theta0
        theta = np.concatenate([theta, np.full(n - theta.size, last)])
    return theta


__all__ = ["fit_impact_decay", "impact_events"]
