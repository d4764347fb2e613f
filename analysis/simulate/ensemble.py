"""Many simulations in one call, spread over the cores: parameter sweeps and initial-state grids.

Each member is an independent run of the compiled integrator (a packed parameter
vector and an initial state); members run in parallel in a numba ``prange`` loop,
so a bifurcation diagram (hundreds of parameter values x hundreds of periods) or a
basin of attraction (a grid of initial states) is one call.

numba's on-disk cache of ``_run_members`` is keyed on this file only: after editing
``integrator.py`` (or the layout ``analysis.model.P``) delete this package's
``__pycache__`` so that the parallel kernel is rebuilt with the new integrator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from analysis.model import P
from analysis.simulate import integrator as ig
from analysis.simulate.simulation import (
    DEFAULT_MAX_STEPS,
    drive_period_s,
    poincare_times,
    record_start_s,
)


@dataclass(frozen=True)
class EnsembleResult:
    """Per-member results of :func:`simulate_ensemble` (first axis: member).

    ``poincare`` is (n, periods, 2) with (theta, theta') at the chosen drive phase,
    NaN-padded where a member has fewer samples (other drive frequency, or it stopped);
    ``samples`` is (n, N, 2) at ``fs_hz`` from each member's record start (None unless
    asked for).  ``contacts`` counts the contacts that ended during the record.
    """

    poincare: np.ndarray
    poincare_t: np.ndarray
    samples: np.ndarray | None
    record_start_s: np.ndarray
    contacts: np.ndarray
    n_steps: np.ndarray
    status: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask of the members that ran to the end."""
        return self.status == "ok"


@numba.njit(parallel=True, cache=True)
def _run_members(
    packed,
    initial,
    t_record,
    pc_first,
    pc_period,
    pc_count,
    t_final,
    fs_hz,
    n_samples,
    rtol,
    atol,
    max_step,
    poincare,
    samples,
    contacts,
    n_steps,
    status,
):
    n = packed.shape[0]
    for i in numba.prange(n):
        p = packed[i].copy()
        state = ig.new_state(0.0, initial[i, 0], initial[i, 1], p)
        out_t = np.empty(n_samples)
        for j in range(n_samples):
            out_t[j] = t_record[i] + j / fs_hz
        out_th = np.empty(n_samples)
        out_om = np.empty(n_samples)
        pc_th = np.empty(pc_count[i])
        pc_om = np.empty(pc_count[i])
        events, n_events, _, _, _, _ = ig.integrate(
            p,
            state,
            out_t,
            out_th,
            out_om,
            pc_first[i],
            pc_period[i],
            pc_th,
            pc_om,
            t_final[i],
            rtol,
            atol,
            max_step,
            DEFAULT_MAX_STEPS,
            np.empty((16, ig.EV_SIZE)),
            0,
            False,
            np.empty((0, 3)),
            0,
        )
        for k in range(pc_count[i]):
            poincare[i, k, 0] = pc_th[k]
            poincare[i, k, 1] = pc_om[k]
        if samples.shape[1] == n_samples:
            for j in range(n_samples):
                samples[i, j, 0] = out_th[j]
                samples[i, j, 1] = out_om[j]
        count = 0
        for e in range(n_events):
            t_out = events[e, ig.EV_T_OUT]
            if events[e, ig.EV_KIND] == ig.KIND_CONTACT and t_record[i] <= t_out <= t_final[i]:
                count += 1
        contacts[i] = count
        n_steps[i] = state[ig.S_STEPS]
        status[i] = state[ig.S_STATUS]


def simulate_ensemble(
    packed: np.ndarray,
    initial: np.ndarray,
    duration_s: float,
    skip_s: float = 0.0,
    poincare_phase: float = 0.0,
    fs_hz: float | None = None,
    rtol: float = 1e-9,
    atol: float = 1e-11,
    max_step_s: float = math.inf,
) -> EnsembleResult:
    """Simulate every member: packed (n, P.SIZE) or (P.SIZE,), initial (n, 2) or (2,).

    Either argument may be a single row, shared by all members (a basin grid over
    initial states with one parameter vector, or a sweep from one initial state).
    Each member skips ``skip_s`` (rounded up to its whole drive periods), then
    records ``duration_s``: Poincare samples at ``poincare_phase`` and, with
    ``fs_hz``, uniform samples.
    """
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if packed.shape[1] != P.SIZE:
        raise ValueError(f"packed has shape {packed.shape}; expected (n, {int(P.SIZE)})")
    if initial.shape[1] != 2:
        raise ValueError(f"initial has shape {initial.shape}; expected (n, 2)")
    n = max(packed.shape[0], initial.shape[0])
    for name, array in (("packed", packed), ("initial", initial)):
        if array.shape[0] not in (1, n):
            raise ValueError(f"{name} has {array.shape[0]} rows; expected 1 or {n}")
    # real (writable, contiguous) copies: numba types read-only views differently
    packed = np.array(np.broadcast_to(packed, (n, int(P.SIZE))), dtype=float, order="C")
    initial = np.array(np.broadcast_to(initial, (n, 2)), dtype=float, order="C")
    if not np.all(np.isfinite(initial)):
        raise ValueError("initial states must be finite")
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s = {duration_s!r}: must be a positive finite number")
    if fs_hz is not None and not (math.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz = {fs_hz!r}: must be a positive finite number")

    t_record = np.array([record_start_s(p, skip_s) for p in packed])
    timing = [
        poincare_times(p, t, t + duration_s, poincare_phase)
        for p, t in zip(packed, t_record, strict=True)
    ]
    pc_first = np.array([first for first, _, _ in timing])
    pc_period = np.array([period for _, period, _ in timing])
    pc_count = np.array([count for _, _, count in timing], dtype=np.int64)
    width = int(pc_count.max()) if n else 0
    poincare = np.full((n, width, 2), np.nan)
    n_samples = math.floor(duration_s * fs_hz + 1e-9) if fs_hz else 0
    samples = np.full((n, n_samples, 2), np.nan) if fs_hz else np.empty((n, 0, 2))
    contacts = np.zeros(n, dtype=np.int64)
    n_steps = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    _run_members(
        packed,
        initial,
        t_record,
        pc_first,
        pc_period,
        pc_count,
        t_record + duration_s,
        float(fs_hz or 1.0),
        n_samples,
        rtol,
        atol,
        float(max_step_s),
        poincare,
        samples,
        contacts,
        n_steps,
        status,
    )
    poincare_t = pc_first[:, None] + np.arange(width)[None, :] * pc_period[:, None]
    poincare_t[np.arange(width)[None, :] >= pc_count[:, None]] = np.nan
    names = np.array([ig.STATUS_NAMES[int(code)] for code in status])
    return EnsembleResult(
        poincare=poincare,
        poincare_t=poincare_t,
        samples=samples if fs_hz else None,
        record_start_s=t_record,
        contacts=contacts,
        n_steps=n_steps,
        status=names,
    )


__all__ = ["EnsembleResult", "drive_period_s", "simulate_ensemble"]
