"""One simulation run: a model and an initial state in, uniform samples, events and Poincare out."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.model import Model
from analysis.packed import P
from analysis.simulate import integrator as ig
from analysis.simulate.result import ContactEvents, SimulationResult, StickEvents, Trajectory


def drive_period_s(p: np.ndarray) -> float:
    """Drive period 2 pi / Omega of a packed vector; inf when the table does not move."""
    forced = p[P.OMEGA_DRIVE] > 0.0 and (p[P.A1] != 0.0 or p[P.A2] != 0.0)
    return 2.0 * math.pi / p[P.OMEGA_DRIVE] if forced else math.inf


def record_start_s(p: np.ndarray, skip_s: float) -> float:
    """Start of the record after a transient: ``skip_s`` rounded up to whole drive periods."""
    period = drive_period_s(p)
    if skip_s <= 0.0 or not math.isfinite(period):
        return max(skip_s, 0.0)
    return math.ceil(skip_s / period - 1e-9) * period


def poincare_times(
    p: np.ndarray, t_start: float, t_end: float, phase: float | None
) -> tuple[float, float, int]:
    """(first time, period, count) of the instants in [t_start, t_end] where the drive phase
    (Omega t + phase0) mod 2 pi equals ``phase``; count 0 when unforced or ``phase`` is None."""
    period = drive_period_s(p)
    if phase is None or not math.isfinite(period):
        return 0.0, 1.0, 0
    omega = p[P.OMEGA_DRIVE]
    offset = phase - p[P.PHASE0]
    m = math.ceil((omega * t_start - offset) / (2.0 * math.pi) - 1e-9)
    first = (offset + 2.0 * math.pi * m) / omega
    if first > t_end:
        return first, period, 0
    return first, period, math.floor((t_end - first) / period + 1e-9) + 1


def check_step_settings(rtol: float, atol: float, max_step_s: float = math.inf) -> None:
    """Refuse tolerances and a step cap the integrator cannot honour, naming the setting:
    rtol and atol positive and finite, rtol >= 1e-14 (below it the error test meets
    rounding), max_step_s positive (inf: no cap)."""
    for name, value in (("rtol", rtol), ("atol", atol)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} = {value!r}: must be a positive finite number")
    if rtol < 1e-14:
        raise ValueError(f"rtol = {rtol!r}: below 1e-14 the error test meets rounding")
    if not max_step_s > 0:
        raise ValueError(f"max_step_s = {max_step_s!r}: must be > 0 (inf for no cap)")


def check_record_settings(duration_s: float, fs_hz: float | None, skip_s: float) -> None:
    """Refuse a record length, sample rate (None: no samples) or transient that makes no
    sense, naming the setting."""
    for name, value in (("duration_s", duration_s), ("fs_hz", fs_hz)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} = {value!r}: must be a positive finite number")
    if not (math.isfinite(skip_s) and skip_s >= 0):
        raise ValueError(f"skip_s = {skip_s!r}: must be >= 0")


@dataclass(frozen=True)
class SimulationSettings:
    """What a run records and how accurately: ``duration_s`` recorded after a transient
    ``skip_s`` (rounded up to whole drive periods when forced), samples at ``fs_hz`` from the
    dense output, a Poincare sample each time the drive phase passes ``poincare_phase``
    (None: none), every segment end with ``dense``; the integrator's tolerances ``rtol``,
    ``atol`` and step cap ``max_step_s`` (inf: none).  Refused with ValueError, naming the
    setting, when the integrator cannot honour it."""

    duration_s: float = 10.0
    fs_hz: float = 1000.0
    skip_s: float = 0.0
    poincare_phase: float | None = 0.0
    dense: bool = False
    rtol: float = 1e-9
    atol: float = 1e-11
    max_step_s: float = math.inf

    def __post_init__(self) -> None:
        check_record_settings(self.duration_s, self.fs_hz, self.skip_s)
        check_step_settings(self.rtol, self.atol, self.max_step_s)


DEFAULT_SETTINGS = SimulationSettings()


def simulate(
    model: Model,
    theta0: float,
    theta_dot0: float = 0.0,
    *,
    settings: SimulationSettings = DEFAULT_SETTINGS,
) -> SimulationResult:
    """Simulate ``model`` from (theta0, theta_dot0) at t = 0; see :func:`simulate_packed`."""
    return simulate_packed(model.pack(), theta0, theta_dot0, settings=settings)


def simulate_packed(
    p: np.ndarray,
    theta0: float,
    theta_dot0: float = 0.0,
    *,
    settings: SimulationSettings = DEFAULT_SETTINGS,
) -> SimulationResult:
    """Simulate a packed parameter vector (layout ``analysis.packed.P``) as ``settings`` say.

    The transient is integrated and discarded; then the record holds the samples, every
    contact and stick interval that ended in it, and the Poincare samples.
    """
    p = np.ascontiguousarray(p, dtype=float)
    if p.shape != (P.SIZE,):
        raise ValueError(f"packed vector has shape {p.shape}; expected ({int(P.SIZE)},)")
    if not (math.isfinite(theta0) and math.isfinite(theta_dot0)):
        raise ValueError(f"initial state ({theta0!r}, {theta_dot0!r}) must be finite")
    fs_hz = settings.fs_hz
    t_rec = record_start_s(p, settings.skip_s)
    n_samples = math.floor(settings.duration_s * fs_hz + 1e-9)
    out_t = np.arange(n_samples, dtype=float)  # t_rec + k / fs, built in place
    out_t /= fs_hz
    out_t += t_rec
    t_final = t_rec + settings.duration_s
    pc_t0, pc_dt, n_pc = poincare_times(p, t_rec, t_final, settings.poincare_phase)
    out_th = np.empty(n_samples)
    out_om = np.empty(n_samples)
    pc_th = np.empty(n_pc)
    pc_om = np.empty(n_pc)
    state = ig.new_state(0.0, float(theta0), float(theta_dot0), p)
    run = ig.Run(
        p, state, ig.StepControl(settings.rtol, settings.atol, settings.max_step_s),
        ig.PoincareSamples(pc_t0, pc_dt, pc_th, pc_om), dense_columns=3 if settings.dense else 0,
    )
    written = run.advance(out_t, out_th, out_om, t_final)
    pc_written = run.poincare_written
    # contacts and stick intervals that ended during the record (not in the transient, nor
    # in the part of the last step beyond its end)
    rows = run.events[: run.n_events]
    rows = rows[(rows[:, ig.EV_T_OUT] >= t_rec) & (rows[:, ig.EV_T_OUT] <= t_final)]
    pc_t = pc_t0 + np.arange(pc_written) * pc_dt
    trajectory = None
    if settings.dense:
        d = run.dense[: run.n_dense]
        trajectory = Trajectory(d[:, 0].copy(), d[:, 1].copy(), d[:, 2].copy())
    return SimulationResult(
        t=out_t[:written],
        theta=out_th[:written],
        theta_dot=out_om[:written],
        fs_hz=float(fs_hz),
        record_start_s=t_rec,
        contacts=ContactEvents.from_rows(rows),
        sticks=StickEvents.from_rows(rows),
        poincare=Trajectory(pc_t, pc_th[:pc_written], pc_om[:pc_written]),
        dense=trajectory,
        n_steps=int(state[ig.S_STEPS]),
        n_rejected=int(state[ig.S_REJECTS]),
        status=ig.STATUS_NAMES[int(state[ig.S_STATUS])],
        final_state=(float(state[ig.S_TB]), float(state[ig.S_THB]), float(state[ig.S_OMB])),
    )
