"""A sweep's channels with known content (a sine of the drive, no physics), for the loaders'
tests; written as a recording by :func:`reference.sweeps.write_marked_recording`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rig.events import StepMark


def sine_sweep(
    amplitudes_m: Sequence[float], *, fs: float = 500.0, frequency_hz: float = 5.0,
    settle_s: float = 1.0, dwell_s: float = 3.0, complete: Sequence[bool] | None = None,
) -> tuple[np.ndarray, np.ndarray, list[StepMark]]:
    """An amplitude sweep's channels (a sine of the drive as the angle, a tach edge every
    period) and its step marks, steps back to back: angle, tach edges, marks."""
    per_step = round((settle_s + dwell_s) * fs)
    n = per_step * len(amplitudes_m)
    t = np.arange(n) / fs
    scale = np.repeat(np.asarray(amplitudes_m) / amplitudes_m[0], per_step)
    angle = 0.05 * scale * np.sin(2.0 * np.pi * frequency_hz * t)
    edges = np.flatnonzero(np.diff(np.floor(frequency_hz * t)) > 0) + 1
    marks = []
    for k, amplitude in enumerate(amplitudes_m):
        first = k * per_step
        marks.append(StepMark(k, 1, frequency_hz, amplitude, first,
                              first + round(settle_s * fs), first + per_step,
                              True if complete is None else complete[k]))
    return angle, edges, marks
