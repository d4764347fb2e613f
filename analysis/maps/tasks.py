"""One task of a map, as any worker runs it: plain arrays in, plain arrays out.

A task is self-contained (its parameter vectors, initial or start state and settings), so
the same function runs in this process, in a local worker process or on a remote machine,
and gives the same numbers: the compiled integrator runs each trajectory on its own,
in the worker's one thread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.dynamics.sweeps import PoincareSettings, continue_along, run_poincare
from analysis.maps.plan import MapPlan, Task
from analysis.model import Drive, Model, RigParameters

STATUSES = ("ok", "over_the_top", "max_steps", "step_size_underflow", "incomplete")
NOT_RUN = -1  # status code of a trajectory no task has written yet


@dataclass(frozen=True)
class TaskInput:
    """What a worker needs for one task.

    ``initial`` is (n, 2); a continuation piece (``chain``) starts from ``initial[0]`` and
    continues from step to step, restarting from ``restart`` after a run that left the
    model (over the top).
    """

    packed: np.ndarray
    initial: np.ndarray
    chain: bool
    restart: np.ndarray
    transient_periods: int
    record_periods: int
    rtol: float
    atol: float


@dataclass(frozen=True)
class TaskOutput:
    """Per trajectory: the state it started from, its Poincare samples (theta, theta' at
    drive phase 0 over the recorded periods), its final state, the contacts during the
    recorded periods and its status (index into STATUSES)."""

    initial: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    final: np.ndarray
    contacts: np.ndarray
    status: np.ndarray


def task_input(plan: MapPlan, task: Task, start_state: np.ndarray | None = None) -> TaskInput:
    """The input of ``task``; a continuation piece after its sweep's first needs the state
    its sweep reached (``start_state``, from the piece before)."""
    initial = plan.initial[task.start : task.stop].copy()
    chain = task.chain_first >= 0
    restart = plan.initial[task.chain_first] if chain else np.full(2, np.nan)
    if chain and task.start != task.chain_first:
        if start_state is None:
            raise ValueError(f"task {task.index} continues a sweep: pass the state it reached")
        initial[0] = start_state
    settings = plan.settings
    return TaskInput(
        packed=plan.packed[plan.point[task.start : task.stop]],
        initial=initial,
        chain=chain,
        restart=np.array(restart, dtype=float),
        transient_periods=settings.transient_periods,
        record_periods=settings.record_periods,
        rtol=settings.rtol,
        atol=settings.atol,
    )


def continued_state(final: np.ndarray, status: int, restart: np.ndarray) -> np.ndarray:
    """Where a continuation sweep's next step starts: the step's final state, or after a run
    that left the model, the sweep's restart state."""
    return np.array(final if status == 0 else restart, dtype=float)


def run_task(inputs: TaskInput) -> TaskOutput:
    """Run every trajectory of the task in this thread (no pool: one task, one core)."""
    settings = PoincareSettings(inputs.transient_periods, inputs.record_periods, inputs.rtol,
                                inputs.atol)
    if inputs.chain:
        (runs,) = continue_along(inputs.packed, inputs.initial[0], settings, workers=1,
                                 restart_state=inputs.restart)
    else:
        runs = run_poincare(inputs.packed, inputs.initial, settings, workers=1)
    status = np.array([STATUSES.index(s) for s in runs.status], dtype=np.int8)
    initial = inputs.initial.copy()
    if inputs.chain:
        for k in range(1, status.size):
            initial[k] = continued_state(runs.final_state[k - 1], status[k - 1], inputs.restart)
    return TaskOutput(initial, runs.theta, runs.theta_dot, runs.final_state, runs.contacts, status)


def warm_up() -> dict[str, str]:
    """Load (or compile, once per machine: numba caches it) the integrator by one short run,
    and say which software this process computes with."""
    from analysis.provenance import DEPENDENCIES, git_commit, package_version

    model = Model(RigParameters(), Drive(amplitude_m=0.001, frequency_hz=10.0))
    run_poincare(model.pack()[None], np.zeros((1, 2)), PoincareSettings(0, 1), workers=1)
    versions = {name: package_version(name) for name in ("impact-rig", *DEPENDENCIES)}
    versions["impact-rig commit"] = (git_commit() or {}).get("commit", "none (installed)")
    return versions
