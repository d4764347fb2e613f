"""Where does the baseline fail?  Its residual sorted by phase of motion, angle, velocity, time,
drive phase and frequency, and a sentence that says what stands out and what it suggests.

Each feature is a ratio that is about 1 (or 0) when the residual is white noise
spread evenly over the record; the words name the ones far from that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.fitting import FitData, FitResult
from analysis.simulate import SimulationResult

CONTACT_GUARD_SAMPLES = 2


@dataclass(frozen=True)
class Localization:
    """The sentence and the numbers behind it."""

    text: str
    features: dict[str, Any] = field(default_factory=dict)


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(math.sqrt(np.mean(x * x))) if x.size else math.nan


def envelope(t: np.ndarray, y: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Times and sizes of the swing (half peak-to-peak between successive turning points)."""
    idx = np.arange(t.size)
    filled = np.interp(idx, idx[valid], y[valid])
    d = np.diff(filled)
    sign = np.sign(d)
    # carry the last nonzero slope through flat (quantised) stretches
    for i in range(1, sign.size):
        if sign[i] == 0:
            sign[i] = sign[i - 1]
    turns = np.flatnonzero(sign[1:] * sign[:-1] < 0) + 1
    if turns.size < 3:
        return np.zeros(0), np.zeros(0)
    values = filled[turns]
    sizes = 0.5 * np.abs(np.diff(values))
    times = 0.5 * (t[turns[1:]] + t[turns[:-1]])
    # noise makes tiny spurious turns: keep swings well above the smallest
    keep = sizes > 0.05 * sizes.max()
    return times[keep], sizes[keep]


def envelope_shape(times: np.ndarray, sizes: np.ndarray) -> dict[str, float]:
    """How well the swing size follows an exponential and a straight line in time."""
    if sizes.size < 6:
        return {}
    positive = sizes > 0
    times, sizes = times[positive], sizes[positive]
    lin = np.polyfit(times, sizes, 1)
    lin_resid = sizes - np.polyval(lin, times)
    expo = np.polyfit(times, np.log(sizes), 1)
    exp_resid = sizes - np.exp(np.polyval(expo, times))
    third = max(2, sizes.size // 3)
    early = -np.polyfit(times[:third], np.log(sizes[:third]), 1)[0]
    late = -np.polyfit(times[-third:], np.log(sizes[-third:]), 1)[0]
    return {
        "linear_fit_rms": _rms(lin_resid),
        "exponential_fit_rms": _rms(exp_resid),
        "decay_rate_early_per_s": float(early),
        "decay_rate_late_per_s": float(late),
    }


def motion_of(data: FitData, sim: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """The model's rate at the record's samples and the samples near a contact (with a guard
    of CONTACT_GUARD_SAMPLES either side), from one simulation of the record."""
    n = data.t.size
    theta_dot = np.full(n, np.nan)
    rate = np.asarray(sim.theta_dot, dtype=float)[:n]
    theta_dot[:rate.size] = rate
    in_contact = np.zeros(n, dtype=bool)
    idx_in = np.floor(sim.contacts.t_in / data.dt).astype(int) - CONTACT_GUARD_SAMPLES
    idx_out = np.ceil(sim.contacts.t_out / data.dt).astype(int) + CONTACT_GUARD_SAMPLES
    for a, b in zip(idx_in, idx_out, strict=True):
        in_contact[max(a, 0):min(b, n)] = True
    return theta_dot, in_contact


def localize(
    data: FitData, baseline: FitResult, theta_dot: np.ndarray, in_contact: np.ndarray
) -> Localization:
    """Describe the baseline's residual (model - data) of a fitted record, given the model's
    rate and its contact samples."""
    f = _residual_features(data, baseline, theta_dot, in_contact)
    # envelope of the data
    times, sizes = envelope(data.t, data.y, data.valid)
    shape = envelope_shape(times, sizes)
    f.update({f"envelope_{k}": v for k, v in shape.items()})
    return Localization("; ".join(_describe(f, shape, data.barrier)), f)


def _residual_features(
    data: FitData, baseline: FitResult, theta_dot: np.ndarray, in_contact: np.ndarray
) -> dict[str, Any]:
    """The residual's size sorted by time, angle, rate, contact, drive phase and frequency."""
    r = baseline.residual
    valid = np.isfinite(r)
    noise = data.noise_rad
    rms = _rms(r)
    f: dict[str, Any] = {"rms_residual_rad": rms, "noise_rad": noise,
                         "rms_over_noise": rms / max(noise, 1e-300)}
    model_theta = np.where(valid, data.y + np.nan_to_num(r), np.nan)
    # constant part: a sensor zero
    f["mean_residual_rad"] = float(np.nanmean(r))
    # time: thirds of the record
    n = r.size
    f["rms_by_time_third"] = [_rms(r[i * n // 3:(i + 1) * n // 3]) for i in range(3)]
    # angle and velocity: residual in the outer and inner halves of each
    amp = np.nanmax(np.abs(model_theta))
    big_angle = np.abs(model_theta) > 0.5 * amp
    f["rms_large_angle_over_small"] = _rms(r[big_angle]) / max(_rms(r[~big_angle]), 1e-300)
    if np.any(np.isfinite(theta_dot)):
        fast = np.abs(theta_dot) > 0.5 * np.nanmax(np.abs(theta_dot))
        f["rms_fast_over_slow"] = _rms(r[fast]) / max(_rms(r[~fast]), 1e-300)
    # correlation of the residual with odd powers of the angle (scale and cubic sensor errors)
    good = valid & np.isfinite(model_theta)
    if np.count_nonzero(good) > 10:
        cube = model_theta[good] ** 3
        f["correlation_with_angle_cubed"] = float(np.corrcoef(r[good], -cube)[0, 1])
    # phase of motion: samples near a contact against free flight
    if in_contact.any():
        edges = np.diff(np.concatenate([[0], in_contact.astype(np.int8), [0]]))
        f["contacts"] = int(np.count_nonzero(edges == 1))
        f["rms_near_contact_rad"] = _rms(r[in_contact])
        f["rms_free_flight_rad"] = _rms(r[~in_contact])
    # drive phase
    if data.drive.is_forced:
        phase = np.mod(data.drive.Omega_rad_s * data.t + data.phase0_rad, 2 * math.pi)
        bins = np.linspace(0, 2 * math.pi, 9)
        f["rms_by_drive_phase"] = [
            _rms(r[(phase >= bins[i]) & (phase < bins[i + 1])]) for i in range(8)
        ]
    # spectrum of the residual: the strongest line, in units of the swing frequency
    filled = np.where(valid, r, 0.0)
    spectrum = np.abs(np.fft.rfft(filled * np.hanning(filled.size)))
    freqs = np.fft.rfftfreq(filled.size, data.dt)
    omega_hz = baseline.values[q.omega_rad_s] / (2 * math.pi)
    if spectrum.size > 2:
        k = int(np.argmax(spectrum[1:])) + 1
        f["residual_peak_hz"] = float(freqs[k])
        f["residual_peak_over_swing_frequency"] = float(freqs[k] / omega_hz)
    return f


def _describe(f: dict[str, Any], shape: dict[str, float], barrier: bool) -> list[str]:
    """The phrases that name what stands out in the residual's features."""
    rms, mean, thirds = f["rms_residual_rad"], f["mean_residual_rad"], f["rms_by_time_third"]
    ratio = f["rms_over_noise"]
    if ratio < 1.3:
        return [
            f"the baseline explains the record within its noise (residual {rms:.2g} rad, "
            f"{ratio:.2g} x the noise)"
        ]
    words = [f"the baseline leaves {rms:.2g} rad rms, {ratio:.3g} x the noise"]
    if shape and not barrier:
        words.append(_envelope_words(shape))
    if abs(mean) > 0.3 * rms:
        words.append(
            f"the residual has a constant part of {mean:.3g} rad: the model's rest angle "
            "differs from the measured one (sensor zero or barrier)"
        )
    worst = int(np.argmax(thirds))
    words.append(
        f"it is largest in the {('first', 'middle', 'last')[worst]} third of the record "
        f"({thirds[worst]:.2g} rad)"
    )
    if "rms_near_contact_rad" in f:
        words.append(_contact_words(f))
    if f["rms_large_angle_over_small"] > 1.5:
        words.append(
            f"it is {f['rms_large_angle_over_small']:.2g} x larger at large angles than near "
            "the rest position"
        )
    corr = f.get("correlation_with_angle_cubed", 0.0)
    if abs(corr) > 0.5:
        words.append(f"it follows the cube of the angle (correlation {corr:.2f})")
    if "residual_peak_over_swing_frequency" in f:
        words.append(
            f"its strongest spectral line is at {f['residual_peak_hz']:.3g} Hz "
            f"({f['residual_peak_over_swing_frequency']:.2f} x the swing frequency)"
        )
    if "rms_by_drive_phase" in f:
        by_phase = np.array(f["rms_by_drive_phase"])
        if np.nanmax(by_phase) > 1.5 * np.nanmin(by_phase):
            k = int(np.nanargmax(by_phase))
            words.append(
                f"it peaks at drive phase {45 * k}-{45 * (k + 1)} degrees"
            )
    return words


def _envelope_words(shape: dict[str, float]) -> str:
    """What the measured envelope's shape says about the damping."""
    lin, ex = shape["linear_fit_rms"], shape["exponential_fit_rms"]
    early, late = shape["decay_rate_early_per_s"], shape["decay_rate_late_per_s"]
    if lin < 0.7 * ex and late > 1.3 * early:
        return (
            "the baseline decays exponentially but the measured envelope falls "
            "linearly in time, its relative decay rate rising from "
            f"{early:.3g}/s to {late:.3g}/s as the swing shrinks - typical of dry friction"
        )
    if early > 1.3 * late:
        return (
            f"the measured swing decays faster at large amplitude ({early:.3g}/s) than "
            f"at small ({late:.3g}/s) - damping that grows with speed, typical of drag "
            "(or a large-swing effect)"
        )
    return (
        f"the envelope is close to exponential (decay rate {early:.3g}/s early, "
        f"{late:.3g}/s late)"
    )


def _contact_words(f: dict[str, Any]) -> str:
    """Whether the residual gathers around the contacts or spreads over free flight."""
    near, free = f["rms_near_contact_rad"], f["rms_free_flight_rad"]
    if near > 1.5 * free:
        return (
            f"it concentrates around the {f['contacts']} contacts ({near:.2g} rad against "
            f"{free:.2g} rad in free flight): the contact phase is mis-modelled"
        )
    return (
        f"it is spread over free flight ({free:.2g} rad) as much as contacts "
        f"({near:.2g} rad)"
    )
