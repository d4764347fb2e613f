"""How much of a cause a forced record shows: the part of its effect on the noiseless reading
that the baseline model cannot absorb by refitting its own parameters, in noise units.

The analysis fits the baseline (docs/MODEL.md section 2) by multiple shooting over segments of
0.4 s, each with its own initial state, sharing omega, zeta, K and mu0.  Here that refit is
done over a few windows of the same length spread over the record: in each, the baseline
(the stated table amplitude as a pure sine) is run from the true state at the window's
start, and the reading minus that run is the cause's effect.  Levenberg-Marquardt steps on
finite-difference sensitivities to omega, zeta, K and mu0 (shared by every window) and to
each window's own initial angle and rate refit the baseline to the reading; what the best
refit leaves is what shows.  The windows are not linked, so the baseline gets more freedom
than the analysis gives it (within bounds far beyond a rig's values): what still shows
here shows there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from reference.simulator import Pendulum, TableMotion, simulate_reference

WINDOW_S = 0.4  # the analysis's segment length: a few drive periods at 10 Hz, a swing at 2 Hz
WINDOWS = 6  # spread evenly over the record
# The refit: a cause whose effect is a hundred noise sigmas but nearly of the baseline's own
# shape (Kelvin-Voigt contact damping against Hunt-Crossley's mu0) needs three or four
# steps before what is left is the cause's and not linearisation error.  It stops when a
# step from a fresh Jacobian gains less than REFIT_GAIN of the RMS (converged for a verdict
# at SHOWS_OVER_NOISE) or no damped step helps, when what is left is below
# HIDDEN_BEYOND_DOUBT of the threshold, or after MAX_STEPS (MAX_JACOBIANS computed afresh,
# Broyden's update in between).
MAX_STEPS = 8
MAX_JACOBIANS = 2
REFIT_GAIN = 0.8
DAMPING_START = 1e-3
DAMPING_TRIALS = 6
HIDDEN_BEYOND_DOUBT = 0.2
# What shows must raise the baseline's residual over the record by a few per cent of the
# noise: RMS 0.3 sigma left unabsorbed makes it sqrt(1 + 0.09) = 1.044 sigma, an
# information-criterion gain of about 0.09 N = 5400 over N = 60 000 samples (against a
# margin of 10 + k ln N ~ 30), and a forecast error whose mean-square excess over the noise,
# 0.09 sigma^2, is several times the scatter a held-out half allows (3 sqrt(2 / 30 000)
# sigma^2 = 0.025 sigma^2).  Below it a refit of omega, zeta, K and mu0 explains the record
# to within what no judge can tell from noise.
SHOWS_OVER_NOISE = 0.3
# Finite-difference steps: relative (logarithmic) for L and K, relative to the value for
# zeta and mu0, absolute for the initial state; large against the integration error, small
# against the response's curvature.
RELATIVE_STEP = 1e-4
ANGLE_STEP_RAD = 1e-5
RATE_STEP_RAD_S = 1e-4
RTOL = 1e-8
ATOL = 1e-10
# The baseline's parameters a refit moves: L and K on a log scale, zeta and mu0 relative to
# the baseline's own value (absolute when it is 0); and how far: L by 20 %, K by a factor of
# 10, zeta and mu0 from 0 to 20 times the rig's.  Far beyond what a rig's own values allow,
# and short of the regions where the contact turns into endless chatter.
REFITTED = ("L_m", "zeta", "K_n", "mu0_s_per_m")
SHIFT_BOUNDS = (np.array([-0.2, -1.0, -math.log(10.0), -1.0]),
                np.array([0.2, 19.0, math.log(10.0), 19.0]))


@dataclass(frozen=True)
class Visibility:
    """A cause's effect on the noiseless reading, RMS over the windows in noise units:
    all of it, and what the best refit of the baseline's parameters and initial states
    leaves."""

    effect_over_noise: float
    visible_over_noise: float
    windows: int

    @property
    def shows(self) -> bool:
        """True when what the refit leaves reaches SHOWS_OVER_NOISE."""
        return self.visible_over_noise >= SHOWS_OVER_NOISE


@dataclass(frozen=True)
class _Window:
    """One stretch of the record: its sample times, the reading there, the true state at
    its start, and the baseline's table motion there."""

    times: np.ndarray
    reading: np.ndarray
    state: np.ndarray
    table: TableMotion


@dataclass(frozen=True)
class Stretch:
    """A run of samples of one table motion (a record, or a sweep's step): the baseline's
    ``table`` there, the true motion ``theta_rad``, ``theta_dot_rad_s`` at ``time_s``, and the
    noiseless sensor output ``reading_rad``."""

    table: TableMotion
    time_s: np.ndarray
    theta_rad: np.ndarray
    theta_dot_rad_s: np.ndarray
    reading_rad: np.ndarray


def window_starts(theta_rad: np.ndarray, time_s: np.ndarray, window_s: float = WINDOW_S,
                  windows: int = WINDOWS) -> np.ndarray:
    """Sample indices where the windows start: evenly spread, each moved on to the first
    sample in the lower half of the swing, so that no window starts inside a contact
    (where the force law's whole history would be charged to one window); fewer, or one
    shorter window, when the record is short."""
    span = float(time_s[-1] - time_s[0])
    if span <= 2 * window_s:
        return np.array([0])
    count = max(1, min(windows, int(span // window_s) - 1))
    nominal = np.searchsorted(time_s, time_s[0] + np.linspace(0.0, span - 2 * window_s, count))
    low = 0.5 * min(float(np.min(theta_rad)), 0.0)
    starts = []
    for index in nominal:
        ahead = np.flatnonzero(theta_rad[index:] <= low)
        moved = index + int(ahead[0]) if ahead.size else index
        starts.append(moved if time_s[moved] - time_s[index] <= window_s else index)
    return np.unique(starts)


def cause_visibility(
    baseline: Pendulum,
    table: TableMotion,
    time_s: np.ndarray,
    theta_rad: np.ndarray,
    theta_dot_rad_s: np.ndarray,
    reading_rad: np.ndarray,
    noise_rad: float,
    *,
    window_s: float = WINDOW_S,
    windows: int = WINDOWS,
) -> Visibility:
    """What of ``reading_rad`` (the noiseless sensor output of the true motion ``theta_rad``,
    ``theta_dot_rad_s`` at ``time_s``) the ``baseline`` pendulum driven by ``table`` cannot
    reproduce after refitting omega, zeta, K, mu0 and each window's initial state; RMS over
    the windows in units of ``noise_rad``."""
    return stretches_visibility(
        baseline, [Stretch(table, time_s, theta_rad, theta_dot_rad_s, reading_rad)],
        noise_rad, window_s=window_s, windows=windows)


def stretches_visibility(
    baseline: Pendulum,
    stretches: Sequence[Stretch],
    noise_rad: float,
    *,
    window_s: float = WINDOW_S,
    windows: int = WINDOWS,
) -> Visibility:
    """:func:`cause_visibility` over several stretches of one rig (a sweep's steps, each
    with its own table motion): ``windows`` windows in each, omega, zeta, K and mu0 refitted
    once for all of them (as the sweep's shared fit does), each window's initial state its
    own."""
    if not (math.isfinite(noise_rad) and noise_rad > 0):
        raise ValueError(f"noise_rad = {noise_rad!r}: expected a positive number")
    if not stretches:
        raise ValueError("stretches: expected at least one")
    chosen = []
    for stretch in stretches:
        arrays = [np.asarray(a, dtype=float) for a in (stretch.time_s, stretch.theta_rad,
                                                       stretch.theta_dot_rad_s,
                                                       stretch.reading_rad)]
        time_s, theta_rad, theta_dot_rad_s, reading_rad = arrays
        if any(a.ndim != 1 or a.shape != time_s.shape for a in arrays) or time_s.size < 2:
            raise ValueError("time_s, theta_rad, theta_dot_rad_s and reading_rad must be 1-d "
                             f"arrays of one length >= 2; got shapes {[a.shape for a in arrays]}")
        for index in window_starts(theta_rad, time_s, window_s, windows):
            stop = int(np.searchsorted(time_s, time_s[index] + window_s, side="right"))
            chosen.append(_Window(time_s[index:stop], reading_rad[index:stop],
                                  np.array([theta_rad[index], theta_dot_rad_s[index]]),
                                  stretch.table))
    shift = np.zeros(len(REFITTED))
    residual = _residual(baseline, shift, chosen, [w.state for w in chosen])
    left = _refit(baseline, chosen, residual, SHOWS_OVER_NOISE * noise_rad)
    return Visibility(effect_over_noise=_rms(residual) / noise_rad,
                      visible_over_noise=left / noise_rad, windows=len(chosen))


def _refit(baseline: Pendulum, windows: list[_Window],
           residual: np.ndarray, threshold_rad: float) -> float:
    """The RMS of the reading minus the best refit found of the baseline's parameters and
    the windows' states (Levenberg-Marquardt; the Jacobian kept up to date by Broyden's
    update while steps gain, recomputed before giving up)."""
    shift = np.zeros(len(REFITTED))
    states = [w.state for w in windows]
    best = _rms(residual)
    rows = np.repeat(np.arange(len(windows)), [w.times.size for w in windows])
    design, fresh = _design(baseline, shift, windows, states, residual), True
    jacobians = 1
    damping = DAMPING_START
    for _ in range(MAX_STEPS):
        norms = np.linalg.norm(design, axis=0)
        usable = norms > 0  # K and mu0 do nothing when no window has a contact
        scaled = design[:, usable] / norms[usable]
        accepted = None
        for _ in range(DAMPING_TRIALS):
            step = np.zeros(design.shape[1])
            step[usable] = _damped_step(scaled, residual, damping) / norms[usable]
            trial_shift = np.clip(shift + step[: shift.size], *SHIFT_BOUNDS)
            step[: shift.size] = trial_shift - shift
            trial_states = [s + step[shift.size + 2 * k: shift.size + 2 * k + 2]
                            for k, s in enumerate(states)]
            try:
                trial = _residual(baseline, trial_shift, windows, trial_states)
            except ValueError:  # a step that drives the pendulum over the top
                trial = None
            if trial is not None and _rms(trial) < best:
                accepted = trial
                damping /= 10.0
                break
            damping *= 10.0
        gained = False
        if accepted is not None:
            previous, best = best, _rms(accepted)
            gained = best < REFIT_GAIN * previous
            design = _broyden(design, step, residual - accepted, rows, shift.size)
            shift, states, residual, fresh = trial_shift, trial_states, accepted, False
        if best < HIDDEN_BEYOND_DOUBT * threshold_rad:
            break
        if not gained:
            if fresh or jacobians == MAX_JACOBIANS:
                break
            # a stale Jacobian may be what stalls: a fresh one before giving up
            design, fresh = _design(baseline, shift, windows, states, residual), True
            jacobians += 1
    return best


def _shifted(baseline: Pendulum, shift: np.ndarray) -> Pendulum:
    """The baseline with its refitted parameters."""
    def scaled(value: float, amount: float) -> float:
        return value + amount * (abs(value) if value != 0 else 1.0)

    return replace(
        baseline,
        L_m=baseline.L_m * math.exp(shift[0]),
        zeta=scaled(baseline.zeta, shift[1]),
        K_n=baseline.K_n * math.exp(shift[2]),
        mu0_s_per_m=scaled(baseline.mu0_s_per_m, shift[3]),
    )


def _residual(baseline: Pendulum, shift: np.ndarray, windows: list[_Window],
              states: list[np.ndarray]) -> np.ndarray:
    """The reading minus the refitted baseline, window after window."""
    pendulum = _shifted(baseline, shift)
    return np.concatenate([w.reading - _run(pendulum, w.table, s, w.times)
                           for w, s in zip(windows, states, strict=True)])


def _design(baseline: Pendulum, shift: np.ndarray, windows: list[_Window],
            states: list[np.ndarray], residual: np.ndarray
            ) -> np.ndarray:
    """Forward-difference sensitivities of the baseline's runs: shared parameters in the
    first columns, then each window's (angle, rate) in a block of its own."""
    base = -residual + np.concatenate([w.reading for w in windows])
    columns = []
    for k in range(shift.size):
        nudged = shift.copy()
        nudged[k] += RELATIVE_STEP
        pendulum = _shifted(baseline, nudged)
        run = np.concatenate([_run(pendulum, w.table, s, w.times)
                              for w, s in zip(windows, states, strict=True)])
        columns.append((run - base) / RELATIVE_STEP)
    design = np.zeros((base.size, shift.size + 2 * len(windows)))
    design[:, : shift.size] = np.column_stack(columns)
    pendulum = _shifted(baseline, shift)
    row = 0
    for k, (window, state) in enumerate(zip(windows, states, strict=True)):
        rows = slice(row, row + window.times.size)
        for j, size in enumerate((ANGLE_STEP_RAD, RATE_STEP_RAD_S)):
            nudged = state.copy()
            nudged[j] += size
            design[rows, shift.size + 2 * k + j] = (
                _run(pendulum, window.table, nudged, window.times) - base[rows]) / size
        row += window.times.size
    return design


def _run(pendulum: Pendulum, table: TableMotion, state: np.ndarray,
         times: np.ndarray) -> np.ndarray:
    """The angle from ``state`` at times[0], sampled at ``times``."""
    return simulate_reference(pendulum, table, float(state[0]), float(state[1]), times,
                              t_start_s=float(times[0]), rtol=RTOL, atol=ATOL).theta_rad


def _broyden(design: np.ndarray, step: np.ndarray, change: np.ndarray, windows: np.ndarray,
             shared: int) -> np.ndarray:
    """Schubert's sparse Broyden update: each window's rows learn from the step in the
    shared parameters and its own state, which is all they depend on."""
    updated = design.copy()
    norms = np.linalg.norm(design, axis=0)
    norms[norms == 0] = 1.0
    scaled_step = step * norms
    for k in range(int(windows.max()) + 1):
        rows = windows == k
        columns = np.r_[0:shared, shared + 2 * k: shared + 2 * k + 2]
        z = scaled_step[columns]
        if not np.any(z):
            continue
        miss = change[rows] - design[np.ix_(rows, columns)] @ step[columns]
        updated[np.ix_(rows, columns)] += np.outer(miss, z * norms[columns]) / (z @ z)
    return updated


def _damped_step(design: np.ndarray, residual: np.ndarray, damping: float) -> np.ndarray:
    """The Levenberg-Marquardt step of unit-norm columns: least squares with damping."""
    columns = design.shape[1]
    stacked = np.vstack([design, math.sqrt(damping) * np.eye(columns)])
    return np.linalg.lstsq(stacked, np.concatenate([residual, np.zeros(columns)]),
                           rcond=None)[0]


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))
