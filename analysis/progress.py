"""How a long computation tells its caller where it stands: lines of text, counts, or a
map's counts with its rate and the time it still needs.

A leaf (it imports nothing of ours) directly under ``analysis``, outside the layers inside
it, so that every layer, ``rig``, ``gui`` and ``harness`` use the same types: one per
meaning, all of them here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

ProgressText = Callable[[str], None]
"""A callback told each stage of a long run as one line of text (the command line prints it
as a progress line, the window shows it beside the run)."""


@dataclass(frozen=True)
class Progress:
    """Where a counted run stands: ``done`` of ``total`` units (runs, tasks, trajectories)."""

    done: int
    total: int


ProgressCounts = Callable[[Progress], None]
"""A callback told a counted run's :class:`Progress` (the Poincare runs of a basin or a
bifurcation diagram)."""


@dataclass(frozen=True)
class MapProgress:
    """Where a map's run stands: tasks and trajectories done of all (this run and earlier
    ones), the rate of this run in trajectories per second and the time it still needs."""

    tasks: Progress
    trajectories: Progress
    elapsed_s: float
    rate_per_s: float
    eta_s: float


MapProgressReport = Callable[[MapProgress], None]
"""A callback told each :class:`MapProgress` of a map's run."""
