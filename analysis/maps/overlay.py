"""A recorded sweep (``impact-rig sweep``) as points to draw over a simulated bifurcation map:
per step the angle at each tachometer pulse of the settled half of its dwell, up and down."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis import quantities as q
from analysis.hdf5_records import load_hdf5_steps
from analysis.records import Record
from recording.errors import RecordFormatError

SWEPT = (q.beta, q.f_drive_hz)  # what a recorded sweep steps: amplitude (as beta) or frequency


@dataclass(frozen=True)
class RecordedSweep:
    """Per step: the swept value, the Poincare angles (rad) and the direction ('up'/'down')."""

    parameter: str
    values: tuple[float, ...]
    theta: tuple[np.ndarray, ...]
    directions: tuple[str, ...]


def recorded_sweep(path: str | Path, parameter: str) -> RecordedSweep:
    """The sweep recorded in ``path`` over ``parameter`` (beta = A / L with the recording's L,
    or the drive frequency); RecordFormatError when the file is no sweep or steps another."""
    if parameter not in SWEPT:
        raise RecordFormatError(
            f"{path}: a recorded sweep steps beta or f_drive_hz, not {parameter}"
        )
    return sweep_from_steps(load_hdf5_steps(path), parameter, str(path))


def sweep_from_steps(steps: Sequence[Record], parameter: str, source: str = "") -> RecordedSweep:
    """A sweep from its steps' records, in the order they were recorded: a step is 'up' when
    its value is not below the one before."""
    values: list[float] = []
    thetas, directions = [], []
    for record in steps:
        drive = record.drive or {}
        if parameter == q.beta:
            value = drive[q.amplitude_m] / record.rig_parameters().L_m
        else:
            value = drive[q.frequency_hz]
        settled = record.tach_indices[record.tach_indices >= record.angle_rad.size // 2]
        directions.append("up" if not values or value >= values[-1] else "down")
        values.append(float(value))
        thetas.append(record.angle_rad[settled])
    if len(set(values)) < 2:
        raise RecordFormatError(f"{source or 'sweep'}: the sweep does not step {parameter}")
    return RecordedSweep(parameter, tuple(values), tuple(thetas), tuple(directions))
