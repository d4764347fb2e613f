"""Start values of a forced record by equation error: the equation of motion in free flight is
linear in its parameters, so a regression of the smoothed angle's second derivative on the
model's terms gives them without simulating.

In flight (docs/MODEL.md section 2, measured angle y = theta + offset):

    theta'' = -2 zeta omega theta' - omega^2 [sin(theta) + (x_t''/g) cos(theta)]

with omega^2 = g / L.  Expanding sin(y - offset) and cos(y - offset) to first order in the
offset makes it linear too.  Samples near the barrier, and a smoothing window around them,
are left out: a contact's second derivative is not resolved by any smoother.  The answer
is only a start: smoothing biases it slightly, and the multiple-shooting fit refines it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from analysis.identify.result import IdentificationError
from analysis.model import table_acceleration

SMOOTHING_S = 0.012  # Savitzky-Golay window: resolves drive harmonics well past 10 Hz
POLYORDER = 3
CONTACT_MARGIN_NOISE = 6.0  # samples above (barrier level - this many noise sigmas) are contact
ROBUST_PASSES = 3
# the contact exclusion level taken is the highest whose misfit is within this factor of
# the least misfit over the levels tried
LEVEL_TOLERANCE = 1.02
LEVEL_KEEPS = 0.75  # ... and that keeps at least this fraction of the highest's samples


@dataclass(frozen=True)
class FlightEstimate:
    """What the flight regression found: omega, zeta, the sensor offset, and the table
    amplitude and phase when they were not known (None otherwise), with the regression's
    rms misfit."""

    omega_rad_s: float
    zeta: float
    offset_rad: float
    amplitude_m: float | None
    rms_rad_s2: float
    n_samples: int
    phase_rad: float | None = None


@dataclass(frozen=True)
class TableMotion:
    """The table's motion as the regression uses it: x_t = A sin(Omega t + phase) +
    A h2 sin(2 (Omega t + phase) + phi2); ``amplitude_m`` and ``phase_rad`` None when
    unknown (the regression then finds the fundamental's amplitude and phase)."""

    omega_rad_s: float
    phase_rad: float | None
    amplitude_m: float | None
    h2: float = 0.0
    phi2_rad: float = 0.0

    def shape(self, t: np.ndarray, phase_rad: float) -> np.ndarray:
        """x_t'' / A (the acceleration per unit amplitude) at the given phase."""
        w = self.omega_rad_s
        return table_acceleration(w * t + phase_rad, w, 1.0, self.h2, self.phi2_rad)


def excursion_maxima(y: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The largest angle of every excursion above the record's median, in time order."""
    z = np.where(valid, y, np.nan)
    centre = float(np.nanmedian(z))
    filled = np.where(np.isfinite(z), z, centre)
    above = (filled > centre).astype(np.int8)
    step = np.diff(above)
    starts = np.flatnonzero(step == 1) + 1  # first sample of each excursion
    ends = np.flatnonzero(step == -1) + 1  # first sample after it
    ends = ends[ends > starts[0]] if starts.size else ends
    return np.array([filled[a:b].max() for a, b in zip(starts, ends, strict=False)])


def barrier_level(y: np.ndarray, valid: np.ndarray,
                  maxima: np.ndarray | None = None) -> float:
    """The measured angle where the swings stop: the median of the upper half of the
    excursions' maxima above the record's median (impacts cluster there); ``maxima`` when
    the caller has them already."""
    maxima = excursion_maxima(y, valid) if maxima is None else maxima
    if maxima.size < 3:
        return float(np.nanmax(np.where(valid, y, np.nan)))
    top = np.sort(maxima)[maxima.size // 2:]
    return float(np.median(top))


def flight_regression(
    t: np.ndarray, y: np.ndarray, valid: np.ndarray, noise_rad: float, table: TableMotion,
    g: float, *, contact_level: float | None = None,
) -> FlightEstimate:
    """omega, zeta, the sensor offset (and the table amplitude when unknown) from the
    flight samples of a uniformly sampled forced record."""
    dt = float(t[1] - t[0])
    window = max(POLYORDER + 2, round(SMOOTHING_S / dt) | 1)
    if y.size < 4 * window:
        raise IdentificationError(f"record of {y.size} samples is too short for a flight fit")
    filled = _filled(y, valid)
    ys = savgol_filter(filled, window, POLYORDER)
    yd = savgol_filter(filled, window, POLYORDER, deriv=1, delta=dt)
    ydd = savgol_filter(filled, window, POLYORDER, deriv=2, delta=dt)
    unusable = ~valid | ~np.isfinite(y)
    sin_y, cos_y = np.sin(ys), np.cos(ys)
    both_known = table.amplitude_m is not None and table.phase_rad is not None
    if both_known:
        acc_g = table.amplitude_m * table.shape(t, table.phase_rad) / g
        columns = [yd, sin_y + acc_g * cos_y, cos_y - acc_g * sin_y]
    else:
        # the fundamental's two quadratures (x_t'' per unit amplitude at phases 0, pi/2),
        # and the second harmonic's: a table that no laser watches may be distorted, and a
        # harmonic the basis lacks is absorbed by the other terms (the gravity term's sign)
        w = table.omega_rad_s
        columns = [yd, sin_y, cos_y, table.shape(t, 0.0) * cos_y / g,
                   table.shape(t, 0.5 * math.pi) * cos_y / g,
                   table_acceleration(w * t, w, 0.0, 1.0, 0.0) * cos_y / g,
                   table_acceleration(w * t, w, 0.0, 1.0, 0.5 * math.pi) * cos_y / g]
    basis = np.column_stack(columns)

    def regress(level: float) -> tuple[np.ndarray, float, np.ndarray]:
        # the smoother spreads a contact over its window: drop the window around every
        # sample above the contact level
        near = unusable | (filled > level)
        use = ~(np.convolve(near.astype(float), np.ones(2 * window + 1), mode="same") > 0)
        use[:window] = use[-window:] = False
        if np.count_nonzero(use) < 50:
            return np.zeros(basis.shape[1]), math.inf, use
        keep = use.copy()
        for _ in range(ROBUST_PASSES):
            coef, *_ = np.linalg.lstsq(basis[keep], -ydd[keep], rcond=None)
            misfit = basis @ coef + ydd
            rms = float(np.sqrt(np.mean(misfit[keep] ** 2)))
            keep = use & (np.abs(misfit) < 4.0 * rms)
        return coef, rms, keep

    margin = CONTACT_MARGIN_NOISE * noise_rad
    if contact_level is not None:
        coef, rms, keep = regress(contact_level - margin)
    else:
        # A soft barrier stops slow impacts well short of the fast ones' peaks, and a
        # contact left among the flight samples swamps the regression: the exclusion level
        # steps down through the excursions' maxima until the misfit stops falling.
        # (a level that leaves out much of the flight is a turning point of the swing's
        # other branch, as on a period-2 orbit, not the barrier's)
        fits = [regress(level - margin) for level in _contact_levels(y, valid)]
        fits = [f for f in fits if f[2].sum() >= LEVEL_KEEPS * fits[0][2].sum()]
        best = min(f[1] for f in fits)
        coef, rms, keep = next(f for f in fits if f[1] <= LEVEL_TOLERANCE * best)
    if not math.isfinite(rms):
        raise IdentificationError(
            "too few samples in free flight for the flight fit (is the pendulum always at the "
            "barrier?)"
        )
    omega2 = coef[1]
    if not omega2 > 0:
        raise IdentificationError(
            "the flight regression found no restoring gravity term: the record does not look "
            "like a pendulum's swing"
        )
    omega = math.sqrt(omega2)
    amplitude = phase = None
    if not both_known:
        # A sin(w t + phase) = A cos(phase) sin(w t) + A sin(phase) sin(w t + pi/2)
        amplitude = float(math.hypot(coef[3], coef[4]) / omega2)
        phase = float(math.atan2(coef[4], coef[3]))
    return FlightEstimate(
        omega_rad_s=omega,
        zeta=float(max(coef[0], 0.0) / (2.0 * omega)),
        offset_rad=float(-coef[2] / omega2),
        amplitude_m=amplitude,
        rms_rad_s2=rms,
        n_samples=int(np.count_nonzero(keep)),
        phase_rad=phase,
    )


def _contact_levels(y: np.ndarray, valid: np.ndarray) -> list[float]:
    """Candidate contact levels, highest first: the barrier level, then quantiles of the
    excursions' maxima down to the lowest of the upper half."""
    maxima = excursion_maxima(y, valid)
    levels = [barrier_level(y, valid, maxima)]
    if maxima.size >= 3:
        levels += [float(q) for q in np.quantile(maxima, [0.6, 0.5, 0.4, 0.3, 0.2, 0.1])]
    return sorted({lv for lv in levels if lv <= levels[0]}, reverse=True)


def _filled(y: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The angle with invalid samples bridged linearly (the smoother needs every sample)."""
    good = valid & np.isfinite(y)
    if good.all():
        return np.asarray(y, dtype=float)
    idx = np.arange(y.size)
    return np.interp(idx, idx[good], y[good])
