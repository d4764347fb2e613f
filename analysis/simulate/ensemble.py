"""Many simulations in one call, spread over the cores: parameter sweeps and initial-state grids.

Each member is an independent run of the compiled integrator (a packed parameter
vector and an initial state).  The integrator releases the GIL, so members run in a
pool of threads, one per core, with the very same compiled code as a single run
(no second, parallel build to compile, and members equal single runs bit for bit).
A bifurcation diagram (hundreds of parameter values x hundreds of periods) or a
basin of attraction (a grid of initial states) is one call.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from analysis.packed import P
from analysis.simulate import integrator as ig
from analysis.simulate.simulation import (
    check_record_settings,
    check_step_settings,
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
    workers: int | None = None,
) -> EnsembleResult:
    """Simulate every member: packed (n, P.SIZE) or (P.SIZE,), initial (n, 2) or (2,).

    Either argument may be a single row, shared by all members (a basin grid over
    initial states with one parameter vector, or a sweep from one initial state).
    Each member skips ``skip_s`` (rounded up to its whole drive periods), then
    records ``duration_s``: Poincare samples at ``poincare_phase`` and, with
    ``fs_hz``, uniform samples.  ``workers`` threads (default: one per core; with 1,
    the members run in the calling thread).
    """
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if packed.ndim != 2 or packed.shape[1] != P.SIZE:
        raise ValueError(f"packed has shape {packed.shape}; expected (n, {int(P.SIZE)})")
    if initial.ndim != 2 or initial.shape[1] != 2:
        raise ValueError(f"initial has shape {initial.shape}; expected (n, 2)")
    n = max(packed.shape[0], initial.shape[0])
    for name, array in (("packed", packed), ("initial", initial)):
        if array.shape[0] not in (1, n):
            raise ValueError(f"{name} has {array.shape[0]} rows; expected 1 or {n}")
    packed = np.array(np.broadcast_to(packed, (n, int(P.SIZE))), dtype=float, order="C")
    initial = np.array(np.broadcast_to(initial, (n, 2)), dtype=float, order="C")
    if not np.all(np.isfinite(initial)):
        raise ValueError("initial states must be finite")
    check_record_settings(duration_s, fs_hz, skip_s)
    check_step_settings(rtol, atol, max_step_s)

    t_record = np.array([record_start_s(p, skip_s) for p in packed])
    timing = [
        poincare_times(p, t, t + duration_s, poincare_phase)
        for p, t in zip(packed, t_record, strict=True)
    ]
    pc_count = np.array([count for _, _, count in timing], dtype=np.int64)
    width = int(pc_count.max()) if n else 0
    n_samples = math.floor(duration_s * fs_hz + 1e-9) if fs_hz else 0
    poincare = np.full((n, width, 2), np.nan)
    poincare_t = np.full((n, width), np.nan)
    samples = np.full((n, n_samples, 2), np.nan) if fs_hz else None
    contacts = np.zeros(n, dtype=np.int64)
    n_steps = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    control = ig.StepControl(rtol, atol, max_step_s)

    def run_member(i: int) -> None:
        p = packed[i]
        first, period, count = timing[i]
        t_final = t_record[i] + duration_s
        out_t = t_record[i] + np.arange(n_samples) / (fs_hz or 1.0)
        out_th = np.empty(n_samples)
        out_om = np.empty(n_samples)
        pc_th = np.empty(count)
        pc_om = np.empty(count)
        state = ig.new_state(0.0, initial[i, 0], initial[i, 1], p)
        run = ig.Run(p, state, control, ig.PoincareSamples(first, period, pc_th, pc_om))
        run.advance(out_t, out_th, out_om, t_final)
        pc_written = run.poincare_written
        poincare[i, :count, 0] = pc_th
        poincare[i, :count, 1] = pc_om
        # (the integrator NaN-fills what a stopped member did not reach; times likewise)
        poincare_t[i, :pc_written] = first + np.arange(pc_written) * period
        if samples is not None:
            samples[i, :, 0] = out_th
            samples[i, :, 1] = out_om
        rows = run.events[: run.n_events]
        ended = rows[:, ig.EV_T_OUT]
        contacts[i] = np.count_nonzero(
            (rows[:, ig.EV_KIND] == ig.KIND_CONTACT) & (ended >= t_record[i]) & (ended <= t_final)
        )
        n_steps[i] = int(state[ig.S_STEPS])
        status[i] = int(state[ig.S_STATUS])

    threads = workers or os.cpu_count() or 1
    if threads == 1:  # one worker: in this thread, no pool (the reference for speed-ups)
        for i in range(n):
            run_member(i)
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            for _ in pool.map(run_member, range(n)):
                pass  # re-raises a member's exception here
    names = np.array([ig.STATUS_NAMES[int(code)] for code in status])
    return EnsembleResult(
        poincare=poincare,
        poincare_t=poincare_t,
        samples=samples,
        record_start_s=t_record,
        contacts=contacts,
        n_steps=n_steps,
        status=names,
    )
