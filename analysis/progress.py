"""How a long computation tells its caller where it stands: lines of text, or counts.

A leaf (it imports nothing of ours) directly under ``analysis``, outside the layers inside
it, so that every layer, ``rig``, ``gui`` and ``harness`` use the same two types.
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
