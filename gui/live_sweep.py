"""A live sweep's measured bifurcation diagram, step by step: each completed step's
dwell taken from the live data (:func:`~gui.live_sweep.step_dwell`, on the GUI thread:
copies only) and judged off it (:func:`~gui.live_sweep.judge_dwell`: its regime and
stroboscopic points, by the judge the sweep's analysis uses,
:func:`analysis.dynamics.measured_regime.judge_record_regime`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Protocol

import numpy as np

from gui.live_data import LiveData
from gui.units import DISPLAY, DisplayUnit
from rig.events import StepMark

SWEPT_PARAMETERS = ("frequency", "amplitude")
DOWN_SHIFT = 0.15  # the way down is drawn this fraction of the steps' spacing to the right


@dataclass(frozen=True)
class StepDwell:
    """One completed step's dwell as the live data held it (the newest part of a dwell
    longer than the data kept): the angle, the tach edges as indices into it."""

    mark: StepMark
    setting: float  # the swept value, SI (Hz or m)
    angle_rad: np.ndarray
    tach_indices: np.ndarray
    sample_rate_hz: float
    held_s: float  # how much of the dwell the live data still held


@dataclass(frozen=True)
class LiveStep:
    """A judged step: its regime's short name and label, and its settled stroboscopic
    points (the angle at drive phase 0 of each settled period)."""

    step: int
    direction: int
    setting: float
    regime: str  # 'period-2', 'chaotic', ..., 'undetermined'
    label: str
    points_rad: np.ndarray
    held_s: float


def step_dwell(data: LiveData, mark: StepMark, parameter: str) -> StepDwell | None:
    """The dwell of ``mark`` as ``data`` still holds it (None when none of it is left, or its
    samples are not contiguous: a gap)."""
    if parameter not in SWEPT_PARAMETERS:
        raise ValueError(f"swept parameter {parameter!r}: expected one of {SWEPT_PARAMETERS}")
    indices, angle = data.angle.since(mark.dwell_start_index)
    keep = indices < mark.dwell_end_index
    indices, angle = indices[keep], angle[keep]
    if indices.size < 2 or np.any(np.diff(indices) != 1):
        return None
    first = int(indices[0])
    edges = np.fromiter((e for e in data.tach_edges if first <= e < int(indices[-1]) + 1),
                        dtype=np.int64)
    setting = mark.frequency_hz if parameter == "frequency" else mark.amplitude_m
    return StepDwell(mark, setting, angle.copy(), edges - first, data.sample_rate_hz,
                     indices.size / data.sample_rate_hz)


def judge_dwell(dwell: StepDwell) -> LiveStep:
    """The step's regime and settled stroboscopic points (blocking: call on a worker)."""
    from analysis.identify.preprocess import noise_and_quantum  # scipy: load when needed
    from analysis.sweep.diagram import judge_step

    noise, _ = noise_and_quantum(dwell.angle_rad)
    tach = dwell.tach_indices if dwell.tach_indices.size else None
    judged = judge_step(dwell.mark.step, dwell.angle_rad, dwell.sample_rate_hz, noise,
                     tach_indices=tach, frequency_hz=dwell.mark.frequency_hz, phase_rad=0.0)
    points = judged.cloud[:, 0] if judged.cloud.size else np.zeros(0)
    return LiveStep(dwell.mark.step, dwell.mark.direction, dwell.setting, judged.short,
                    judged.label, points, dwell.held_s)


class _DiagramStep(Protocol):
    setting: float
    direction: int
    points_rad: np.ndarray


def diagram_points(steps: Sequence[_DiagramStep], unit: DisplayUnit,
                   direction: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The diagram's points of ``steps`` (those of one ``direction`` when given): x the swept
    value in ``unit``, the way down shifted right by DOWN_SHIFT of the steps' spacing, y the
    angle in display units."""
    spacing = step_spacing([unit.show(s.setting) for s in steps])
    xs, ys = [np.zeros(0)], [np.zeros(0)]
    for step in steps:
        if direction is not None and step.direction != direction:
            continue
        shift = DOWN_SHIFT * spacing if step.direction < 0 else 0.0
        xs.append(np.full(step.points_rad.size, unit.show(step.setting) + shift))
        ys.append(DISPLAY["angle"].show(step.points_rad))
    return np.concatenate(xs), np.concatenate(ys)


def step_spacing(settings: Sequence[float]) -> float:
    """The least spacing between distinct settings (1 when there is only one)."""
    return min((b - a for a, b in pairwise(sorted(set(settings)))), default=1.0)
