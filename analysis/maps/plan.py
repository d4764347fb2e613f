"""What a map computes: its points, every trajectory in a fixed order, and the batched tasks.

A map is a list of trajectories, each a run of one point's model from one initial state.
Their order is fixed by the map alone (never by who computes them), and so are the
random initial states: drawn from the map's seed and the point's index.  Tasks are
contiguous ranges of that list: a piece of a continuation sweep (each step starts where
the one before ended, so the pieces of one sweep run in order) or a batch of independent
runs.  Any worker count, or none, therefore computes the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from analysis.maps.axes import Axis
from analysis.model import P

KINDS = ("bifurcation", "regimes", "basins")
ROLE_UP, ROLE_DOWN, ROLE_RANDOM, ROLE_GRID = 0, 1, 2, 3
ROLE_NAMES = ("sweep up", "sweep down", "random initial state", "grid initial state")
BASIN_AXES = ("theta0", "omega0")  # the initial angle [rad] and rate [rad/s] of a basin map
# Random initial states: theta0 uniform in [-IC_THETA_RAD, theta_b], theta_dot0 uniform in
# +-IC_RATE_FRACTION * omega (the rate of a free swing of about IC_THETA_RAD).
IC_THETA_RAD = 0.6
IC_RATE_FRACTION = 0.6
MIN_RECORD_PERIODS = 50  # the 0-1 test that names non-periodic attractors needs 50 samples
TASKS_PER_MAP = 64  # the automatic batch aims at about this many tasks ...
BATCH_RANGE = (64, 1024)  # ... within these trajectories per task


class PlanError(ValueError):
    """Settings that do not make a map; the message says which and why."""


@dataclass(frozen=True)
class MapSettings:
    """How each trajectory runs and how the map is cut into tasks.

    ``ics`` random initial states per point (bifurcation and regime maps); ``batch``
    trajectories per task (0: chosen from the map's size, :func:`auto_batch`).
    """

    transient_periods: int
    record_periods: int
    ics: int = 0
    seed: int = 0
    batch: int = 0
    rtol: float = 1e-8
    atol: float = 1e-10

    def __post_init__(self) -> None:
        if self.transient_periods < 0:
            raise PlanError(f"transient periods = {self.transient_periods}: must be >= 0")
        if self.record_periods < MIN_RECORD_PERIODS:
            raise PlanError(
                f"record periods = {self.record_periods}: need at least {MIN_RECORD_PERIODS} "
                "(the 0-1 test that tells chaotic from quasi-periodic attractors needs them)"
            )
        if self.ics < 0 or self.batch < 0 or self.seed < 0:
            raise PlanError("ics, batch and seed must be >= 0")
        if not (0 < self.rtol < 1 and 0 < self.atol < 1):
            raise PlanError(f"rtol {self.rtol}, atol {self.atol}: tolerances must lie in (0, 1)")

    def as_dict(self) -> dict[str, float | int]:
        """Plain values for a file's settings."""
        return {
            "transient_periods": self.transient_periods,
            "record_periods": self.record_periods,
            "ics": self.ics,
            "seed": self.seed,
            "batch": self.batch,
            "rtol": self.rtol,
            "atol": self.atol,
        }


@dataclass(frozen=True)
class Task:
    """Trajectories ``start`` to ``stop`` (excluded).  ``chain_first`` is the first trajectory
    of the continuation sweep this task continues (-1: independent runs)."""

    index: int
    start: int
    stop: int
    chain_first: int = -1

    @property
    def size(self) -> int:
        """Trajectories in the task."""
        return self.stop - self.start


@dataclass(frozen=True)
class MapPlan:
    """Everything a map computes, in order.

    ``packed`` holds one parameter vector per point (points in C order over the
    parameter axes); per trajectory ``point``, ``role`` and ``initial`` (NaN for the
    steps of a continuation sweep after its first: they start where the step before ended).
    """

    kind: str
    axes: tuple[Axis, ...]
    settings: MapSettings
    packed: np.ndarray
    point: np.ndarray
    role: np.ndarray
    initial: np.ndarray
    tasks: tuple[Task, ...] = field(default=())

    @property
    def trajectories(self) -> int:
        """Trajectories in the map."""
        return int(self.point.size)

    @property
    def batch(self) -> int:
        """Trajectories per task (the largest task)."""
        return max(task.size for task in self.tasks)


def auto_batch(trajectories: int) -> int:
    """Trajectories per task: about TASKS_PER_MAP tasks, clipped to BATCH_RANGE.

    The scheduler costs a few milliseconds per task (benchmarks/bench_maps.py) and a
    trajectory of a few hundred drive periods a few milliseconds, so 64 or more
    trajectories per task keep the overhead near 1 %; a map of some thousand trajectories
    still gets enough tasks to keep every worker busy to the end.
    """
    low, high = BATCH_RANGE
    return int(min(high, max(low, math.ceil(trajectories / TASKS_PER_MAP))))


def bifurcation_plan(
    packed: np.ndarray,
    axis: Axis,
    settings: MapSettings,
    start_state: tuple[float, float] = (0.0, 0.0),
) -> MapPlan:
    """Sweeps up and down ``axis`` by continuation from ``start_state``, plus ``settings.ics``
    random initial states per point.  ``packed``: one vector per value of ``axis``."""
    packed = _check_packed(packed, axis.count)
    order = np.argsort(axis.values, kind="stable")  # the up sweep: ascending values
    n, m = axis.count, settings.ics
    point = np.concatenate([order, order[::-1], np.repeat(np.arange(n), m)])
    role = np.concatenate(
        [np.full(n, ROLE_UP), np.full(n, ROLE_DOWN), np.full(n * m, ROLE_RANDOM)]
    ).astype(np.int8)
    initial = np.full((point.size, 2), np.nan)
    initial[[0, n]] = start_state
    initial[2 * n :] = _random_states(packed, settings.seed, m)
    batch = settings.batch or auto_batch(point.size)
    tasks = _chain_tasks(0, n, batch) + _chain_tasks(n, 2 * n, batch)
    tasks += _batch_tasks(2 * n, point.size, batch)
    return _plan("bifurcation", (axis,), settings, packed, point, role, initial, tasks)


def regime_plan(packed: np.ndarray, axes: tuple[Axis, Axis], settings: MapSettings) -> MapPlan:
    """``settings.ics`` random initial states at every point of the grid ``axes[0] x axes[1]``
    (``packed``: one vector per point, C order)."""
    if settings.ics < 1:
        raise PlanError("a regime map needs at least 1 initial state per point (--ics)")
    points = axes[0].count * axes[1].count
    packed = _check_packed(packed, points)
    point = np.repeat(np.arange(points), settings.ics)
    role = np.full(point.size, ROLE_RANDOM, dtype=np.int8)
    initial = _random_states(packed, settings.seed, settings.ics)
    tasks = _batch_tasks(0, point.size, settings.batch or auto_batch(point.size))
    return _plan("regimes", axes, settings, packed, point, role, initial, tasks)


def basin_plan(packed: np.ndarray, axes: tuple[Axis, Axis], settings: MapSettings) -> MapPlan:
    """One model (``packed``) from every initial state of the grid theta0 x omega0 (``axes``,
    in that order); trajectories run over theta0 fastest."""
    if tuple(axis.name for axis in axes) != BASIN_AXES:
        raise PlanError(f"a basin map varies {' and '.join(BASIN_AXES)}, in that order")
    packed = _check_packed(np.atleast_2d(packed), 1)
    grid_theta, grid_rate = np.meshgrid(axes[0].values, axes[1].values)
    initial = np.column_stack([grid_theta.ravel(), grid_rate.ravel()])
    point = np.zeros(initial.shape[0], dtype=np.int64)
    role = np.full(point.size, ROLE_GRID, dtype=np.int8)
    tasks = _batch_tasks(0, point.size, settings.batch or auto_batch(point.size))
    return _plan("basins", axes, settings, packed, point, role, initial, tasks)


def random_initial_states(packed_point: np.ndarray, seed: int, point: int, count: int):
    """``count`` initial states of one point, drawn from (seed, point index) alone."""
    rng = np.random.default_rng([seed, point])
    theta = rng.uniform(-IC_THETA_RAD, packed_point[P.THETA_B], count)
    rate_max = IC_RATE_FRACTION * math.sqrt(packed_point[P.OMEGA2])
    rate = rng.uniform(-rate_max, rate_max, count)
    return np.column_stack([theta, rate])


def _random_states(packed: np.ndarray, seed: int, count: int) -> np.ndarray:
    if count == 0:
        return np.empty((0, 2))
    return np.concatenate(
        [random_initial_states(p, seed, k, count) for k, p in enumerate(packed)]
    )


def _check_packed(packed: np.ndarray, points: int) -> np.ndarray:
    packed = np.asarray(packed, dtype=float)
    if packed.shape != (points, P.SIZE):
        raise PlanError(f"packed has shape {packed.shape}; expected ({points}, {int(P.SIZE)})")
    if not np.all(packed[:, P.OMEGA_DRIVE] > 0):
        raise PlanError("every point of a map needs a drive frequency > 0")
    return packed


def _chain_tasks(start: int, stop: int, batch: int) -> list[tuple[int, int, int]]:
    return [(s, min(stop, s + batch), start) for s in range(start, stop, batch)]


def _batch_tasks(start: int, stop: int, batch: int) -> list[tuple[int, int, int]]:
    return [(s, min(stop, s + batch), -1) for s in range(start, stop, batch)]


def _plan(kind, axes, settings, packed, point, role, initial, ranges) -> MapPlan:
    tasks = tuple(Task(k, *bounds) for k, bounds in enumerate(ranges))
    return MapPlan(
        kind, tuple(axes), settings, packed, np.asarray(point, dtype=np.int64), role, initial,
        tasks,
    )
