"""Running many simulations for sweeps and basin maps: Poincare orbits out, spread over processes.

Bifurcation diagrams and basins of attraction need hundreds to tens of thousands of
runs; each run here is a call of :func:`analysis.simulate.simulate_packed` that keeps
only the Poincare samples and the final state.  Independent runs are split into
chunks handed to worker processes (numba code holds the GIL, so threads would not help).
"""

from __future__ import annotations

import itertools
import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from multiprocessing import get_all_start_methods, get_context

import numpy as np

from analysis.model import Model, P
from analysis.simulate import simulate_packed

Progress = Callable[[int, int], None]  # (runs done, runs in all)


@dataclass(frozen=True)
class PoincareRuns:
    """Poincare samples of n runs: (n, k) angles and rates (NaN where a run stopped early)."""

    theta: np.ndarray
    theta_dot: np.ndarray
    final_state: np.ndarray  # (n, 2) theta, theta_dot at the end (drive phase 0 again)
    status: tuple[str, ...]


def model_at_beta(model: Model, beta: float) -> Model:
    """The same model with drive amplitude A = beta L (beta = A / L, MODEL.md section 4)."""
    if not beta >= 0:
        raise ValueError(f"beta = {beta!r}: the amplitude ratio must be >= 0")
    if model.drive.frequency_hz <= 0:
        raise ValueError("a beta sweep needs a drive frequency > 0 (model.drive.frequency_hz)")
    drive = replace(model.drive, amplitude_m=float(beta) * model.rig.L_m)
    return replace(model, drive=drive)


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of worker processes, forked when that is safe.

    Forking copies the loaded numba code (fast start) and, unlike spawn, needs no
    ``if __name__ == "__main__"`` guard in the caller's script; but forking a process
    that runs other threads can deadlock, so such callers (a GUI) get spawn.
    """
    safe_to_fork = threading.active_count() == 1 and "fork" in get_all_start_methods()
    context = get_context("fork" if safe_to_fork else "spawn")
    return ProcessPoolExecutor(workers, mp_context=context)


def default_workers() -> int:
    """Worker processes to use: the cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def run_poincare(
    packed: np.ndarray,
    initial: np.ndarray,
    *,
    transient_periods: int,
    record_periods: int,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    workers: int | None = None,
    progress: Progress | None = None,
) -> PoincareRuns:
    """Simulate runs (packed (n, P.SIZE), initial (n, 2)) and keep their Poincare samples.

    Each run integrates ``transient_periods`` drive periods, then records one sample
    per period for ``record_periods`` periods.  ``progress(done, total)`` is called as
    chunks of runs finish.
    """
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if packed.shape[0] != initial.shape[0] or initial.shape[1] != 2:
        raise ValueError(
            f"packed {packed.shape} and initial {initial.shape} must be (n, P.SIZE) and (n, 2)"
        )
    if transient_periods < 0 or record_periods < 1:
        raise ValueError("transient_periods must be >= 0 and record_periods >= 1")
    n = packed.shape[0]
    workers = min(workers or default_workers(), n)
    settings = (transient_periods, record_periods, rtol, atol)
    # Process start-up costs up to a second: not worth it for small jobs.
    in_process = workers <= 1 or n < 4 * workers
    bounds = np.linspace(0, n, min(n, 50 if in_process else 8 * workers) + 1).astype(int)
    chunks = [(a, b) for a, b in itertools.pairwise(bounds) if b > a]
    parts: list[PoincareRuns | None] = [None] * len(chunks)
    done = 0
    if in_process:
        for k, (a, b) in enumerate(chunks):
            parts[k] = _run_chunk(packed[a:b], initial[a:b], *settings)
            done += b - a
            if progress is not None:
                progress(done, n)
    else:
        with process_pool(workers) as pool:
            futures = {
                pool.submit(_run_chunk, packed[a:b], initial[a:b], *settings): k
                for k, (a, b) in enumerate(chunks)
            }
            for future in as_completed(futures):
                k = futures[future]
                parts[k] = future.result()
                done += chunks[k][1] - chunks[k][0]
                if progress is not None:
                    progress(done, n)
    return PoincareRuns(
        np.concatenate([part.theta for part in parts]),
        np.concatenate([part.theta_dot for part in parts]),
        np.concatenate([part.final_state for part in parts]),
        tuple(s for part in parts for s in part.status),
    )


def continue_along(
    packed: np.ndarray,
    initial_state: tuple[float, float],
    *,
    transient_periods: int,
    record_periods: int,
    rtol: float = 1e-8,
    atol: float = 1e-10,
) -> PoincareRuns:
    """Sweep in the given order, each run starting from the final state of the one before.

    A run that leaves the model's regime (over the top) restarts the next one from
    ``initial_state``.
    """
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    n = packed.shape[0]
    theta = np.full((n, record_periods), np.nan)
    theta_dot = np.full((n, record_periods), np.nan)
    final = np.full((n, 2), np.nan)
    status = []
    state = tuple(map(float, initial_state))
    for i in range(n):
        run = _run_chunk(
            packed[i : i + 1], np.array([state]), transient_periods, record_periods, rtol, atol
        )
        theta[i], theta_dot[i], final[i] = run.theta[0], run.theta_dot[0], run.final_state[0]
        status.append(run.status[0])
        state = tuple(final[i]) if run.status[0] == "ok" else tuple(map(float, initial_state))
    return PoincareRuns(theta, theta_dot, final, tuple(status))


def _run_chunk(
    packed: np.ndarray,
    initial: np.ndarray,
    transient_periods: int,
    record_periods: int,
    rtol: float,
    atol: float,
) -> PoincareRuns:
    n = packed.shape[0]
    theta = np.full((n, record_periods), np.nan)
    theta_dot = np.full((n, record_periods), np.nan)
    final = np.full((n, 2), np.nan)
    status = []
    for i in range(n):
        omega = packed[i, P.OMEGA_DRIVE]
        if not omega > 0:
            raise ValueError(f"run {i}: the drive frequency must be > 0 for Poincare samples")
        period = 2.0 * math.pi / omega
        result = simulate_packed(
            packed[i],
            float(initial[i, 0]),
            float(initial[i, 1]),
            duration_s=record_periods * period,
            # few uniform samples: only the Poincare samples and the final state are kept
            fs_hz=1.0 / period,
            skip_s=transient_periods * period,
            poincare_phase=0.0,
            rtol=rtol,
            atol=atol,
        )
        k = min(record_periods, result.poincare.theta.size)
        theta[i, :k] = result.poincare.theta[:k]
        theta_dot[i, :k] = result.poincare.theta_dot[:k]
        final[i] = result.final_state[1], result.final_state[2]
        status.append(result.status)
    return PoincareRuns(theta, theta_dot, final, tuple(status))
