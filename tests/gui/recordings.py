"""Recordings with known content, written by the project's real Recorder (real HDF5 files)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from rig.events import DriveSetting, StepMark
from rig.recorder import ChannelSpec, Recorder, RecordingMetadata

RIG = {"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095, "g": 9.81}


def write_recording(
    path: Path,
    angle: np.ndarray,
    fs: float,
    *,
    table: np.ndarray | None = None,
    tach_period: int = 0,
    experiment: str = "forced",
    block: int = 100,
    drive: DriveSetting | None = None,
    first_index: int = 0,
    rig: dict[str, float] | None = None,
    annotations: Sequence[DriveSetting | StepMark] = (),
) -> Path:
    """Write ``angle`` (and ``table``, tach pulses every ``tach_period`` samples) as a recording
    whose device sample indices begin at ``first_index``; ``drive`` is the drive in force at
    the start, ``annotations`` later drive settings and sweep step marks; ``rig`` the rig
    metadata (default RIG)."""
    specs = [ChannelSpec("angle", "samples", "rad", fs, raw_dtype="int32")]
    if table is not None:
        specs.append(ChannelSpec("table", "samples", "m", fs, raw_dtype="int32"))
    specs.append(ChannelSpec("tach", "pulses", "", fs))
    meta = RecordingMetadata(
        experiment=experiment,
        rig=RIG if rig is None else rig,
        roles={"angle": "angle", "table": "table", "tach": "tach"},
        drive=None
        if drive is None
        else {"frequency_hz": drive.frequency_hz, "amplitude_m": drive.amplitude_m},
    )
    with Recorder(path, specs, meta) as recorder:
        for event in ([drive] if drive is not None else []) + list(annotations):
            recorder.add(event, 0.0)
        for start in range(0, angle.size, block):
            stop = min(start + block, angle.size)
            t0 = start / fs
            first = first_index + start
            values = angle[start:stop]
            recorder.add(
                SampleBlock(
                    "angle", first, t0, fs, np.round(values * 1e6).astype(np.int32), values
                ),
                t0,
            )
            if table is not None:
                part = table[start:stop]
                recorder.add(
                    SampleBlock(
                        "table", first, t0, fs, np.round(part * 1e6).astype(np.int32), part
                    ),
                    t0,
                )
            edges = np.arange(start, stop)
            edges = first_index + (edges[edges % tach_period == 0] if tach_period else edges[:0])
            recorder.add(PulseBlock("tach", first, first_index + stop, edges, edges / fs), t0)
    return path
