"""Running many simulations for sweeps and basin maps: Poincare orbits out, spread over the cores.

Bifurcation diagrams and basins of attraction need hundreds to tens of thousands of
runs.  Independent runs go to :func:`analysis.simulate.simulate_ensemble` (a pool of
threads over the GIL-free integrator) in a few chunks, so that progress can be reported;
continuation sweeps advance several sweeps in lockstep, one ensemble call per step.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import numpy as np

from analysis.model import Model
from analysis.packed import P
from analysis.progress import Progress, ProgressCounts
from analysis.simulate import simulate_ensemble


@dataclass(frozen=True)
class PoincareRuns:
    """Poincare samples of n runs: (n, k) angles and rates (NaN where a run stopped early)."""

    theta: np.ndarray
    theta_dot: np.ndarray
    final_state: np.ndarray  # (n, 2) theta, theta_dot at the end (drive phase 0 again)
    status: tuple[str, ...]
    contacts: np.ndarray  # (n,) contacts that ended during the recorded periods


@dataclass(frozen=True)
class PoincareSettings:
    """How each run of a sweep or map goes: drive periods integrated before sampling, then
    one Poincare sample a period for ``record_periods``, at the integrator's tolerances."""

    transient_periods: int
    record_periods: int
    rtol: float = 1e-8
    atol: float = 1e-10

    def __post_init__(self) -> None:
        if self.transient_periods < 0 or self.record_periods < 1:
            raise ValueError("transient_periods must be >= 0 and record_periods >= 1")


def model_at_beta(model: Model, beta: float) -> Model:
    """The same model with drive amplitude A = beta L (beta = A / L, docs/MODEL.md section 4)."""
    if not beta >= 0:
        raise ValueError(f"beta = {beta!r}: the amplitude ratio must be >= 0")
    if model.drive.frequency_hz <= 0:
        raise ValueError("a beta sweep needs a drive frequency > 0 (model.drive.frequency_hz)")
    drive = replace(model.drive, amplitude_m=float(beta) * model.rig.L_m)
    return replace(model, drive=drive)


def default_workers() -> int:
    """Threads an ensemble uses unless capped: one per core."""
    return os.cpu_count() or 1


def run_poincare(
    packed: np.ndarray,
    initial: np.ndarray,
    settings: PoincareSettings,
    *,
    workers: int | None = None,
    progress: ProgressCounts | None = None,
) -> PoincareRuns:
    """Simulate runs (packed (n, P.SIZE), initial (n, 2)) and keep their Poincare samples.

    Each run integrates ``settings.transient_periods`` drive periods, then records one
    sample per period for ``settings.record_periods`` periods (rows may differ in drive
    frequency).  ``workers`` caps the threads; ``progress`` is told the runs done of all
    (a :class:`~analysis.progress.Progress`) as chunks of runs finish.
    """
    packed, initial = _check_runs(packed, initial)
    n = packed.shape[0]
    chunk = max(1, math.ceil(n / 20), 16 * default_workers())
    parts = []
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        parts.append(
            _ensemble(packed[start:stop], initial[start:stop], settings, workers)
        )
        if progress is not None:
            progress(Progress(stop, n))
    return PoincareRuns(
        np.concatenate([part.theta for part in parts]),
        np.concatenate([part.theta_dot for part in parts]),
        np.concatenate([part.final_state for part in parts]),
        tuple(s for part in parts for s in part.status),
        np.concatenate([part.contacts for part in parts]),
    )


def continue_along(
    packed: np.ndarray,
    initial_state: tuple[float, float] | np.ndarray,
    settings: PoincareSettings,
    *,
    workers: int | None = None,
    progress: ProgressCounts | None = None,
    restart_state: tuple[float, float] | np.ndarray | None = None,
) -> tuple[PoincareRuns, ...]:
    """Continuation sweeps: each step starts from the final state of the step before.

    ``packed`` is (steps, P.SIZE) for one sweep or (sweeps, steps, P.SIZE) for several
    advanced in lockstep (one ensemble call of ``sweeps`` members per step, e.g. the
    up and down sweeps in parallel).  ``initial_state`` is (2,) or (sweeps, 2).  A run
    that leaves the model's regime (over the top) restarts the next step from
    ``restart_state`` (default: the initial state; a sweep continued in pieces passes
    its first piece's).  Returns one :class:`PoincareRuns` per sweep, in step order.
    """
    packed = np.asarray(packed, dtype=float)
    if packed.ndim == 2:
        packed = packed[None]
    if packed.ndim != 3 or packed.shape[2] != P.SIZE:
        raise ValueError(f"packed has shape {packed.shape}; expected (sweeps, steps, {P.SIZE})")
    sweeps, steps = packed.shape[:2]
    start = np.broadcast_to(np.asarray(initial_state, dtype=float), (sweeps, 2)).copy()
    restart = start if restart_state is None else np.broadcast_to(
        np.asarray(restart_state, dtype=float), (sweeps, 2)
    )
    theta = np.full((sweeps, steps, settings.record_periods), np.nan)
    theta_dot = np.full((sweeps, steps, settings.record_periods), np.nan)
    final = np.full((sweeps, steps, 2), np.nan)
    status = np.empty((sweeps, steps), dtype=object)
    contacts = np.zeros((sweeps, steps), dtype=np.int64)
    state = start.copy()
    for k in range(steps):
        run = _ensemble(packed[:, k], state, settings, workers)
        theta[:, k], theta_dot[:, k], final[:, k] = run.theta, run.theta_dot, run.final_state
        status[:, k] = run.status
        contacts[:, k] = run.contacts
        ok = np.array(run.status) == "ok"
        state = np.where(ok[:, None], run.final_state, restart)
        if progress is not None:
            progress(Progress((k + 1) * sweeps, steps * sweeps))
    return tuple(
        PoincareRuns(theta[m], theta_dot[m], final[m], tuple(status[m]), contacts[m])
        for m in range(sweeps)
    )


def _check_runs(packed, initial):
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if packed.shape[0] != initial.shape[0] or initial.shape[1] != 2:
        raise ValueError(
            f"packed {packed.shape} and initial {initial.shape} must be (n, P.SIZE) and (n, 2)"
        )
    return packed, initial


def _ensemble(
    packed: np.ndarray, initial: np.ndarray, settings: PoincareSettings, workers: int | None
) -> PoincareRuns:
    """Ensemble calls, one per drive frequency; the Poincare sample at the record's end is
    the final state.  (Members run independently, so the grouping does not change them.)"""
    omega = packed[:, P.OMEGA_DRIVE]
    if not np.all(omega > 0):
        raise ValueError("every run needs a drive frequency > 0 for Poincare samples")
    n = packed.shape[0]
    record_periods = settings.record_periods
    theta = np.full((n, record_periods), np.nan)
    theta_dot = np.full_like(theta, np.nan)
    final = np.full((n, 2), np.nan)
    contacts = np.zeros(n, dtype=np.int64)
    status = np.empty(n, dtype=object)
    for frequency in np.unique(omega):
        rows = np.flatnonzero(omega == frequency)
        period = 2.0 * math.pi / float(frequency)
        result = simulate_ensemble(
            packed[rows],
            initial[rows],
            duration_s=record_periods * period,
            skip_s=settings.transient_periods * period,
            poincare_phase=0.0,
            rtol=settings.rtol,
            atol=settings.atol,
            workers=workers,
        )
        samples = result.poincare[:, : record_periods + 1]
        usable = min(record_periods, samples.shape[1])
        theta[rows, :usable] = samples[:, :usable, 0]
        theta_dot[rows, :usable] = samples[:, :usable, 1]
        if samples.shape[1] == record_periods + 1:
            final[rows] = samples[:, record_periods]
        contacts[rows] = result.contacts
        status[rows] = [str(s) for s in result.status]
    # a run without its closing sample did not reach the end: treat it as failed
    names = tuple(
        s if np.all(np.isfinite(f)) else (s if s != "ok" else "incomplete")
        for s, f in zip(status, final, strict=True)
    )
    return PoincareRuns(theta, theta_dot, final, names, contacts)
