"""Recordings with known content, written by the project's real Recorder (real HDF5 files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from rig.events import DriveSetting
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
) -> Path:
    """Write ``angle`` (and ``table``, tach pulses every ``tach_period`` samples) as a recording."""
    specs = [ChannelSpec("angle", "samples", "rad", fs, raw_dtype="int32")]
    if table is not None:
        specs.append(ChannelSpec("table", "samples", "m", fs, raw_dtype="int32"))
    specs.append(ChannelSpec("tach", "pulses", "", fs))
    meta = RecordingMetadata(
        experiment=experiment,
        rig=RIG,
        roles={"angle": "angle", "table": "table", "tach": "tach"},
        drive=None
        if drive is None
        else {"frequency_hz": drive.frequency_hz, "amplitude_m": drive.amplitude_m},
    )
    with Recorder(path, specs, meta) as recorder:
        if drive is not None:
            recorder.add(drive, 0.0)
        for start in range(0, angle.size, block):
            stop = min(start + block, angle.size)
            t0 = start / fs
            values = angle[start:stop]
            recorder.add(
                SampleBlock(
                    "angle", start, t0, fs, np.round(values * 1e6).astype(np.int32), values
                ),
                t0,
            )
            if table is not None:
                part = table[start:stop]
                recorder.add(
                    SampleBlock(
                        "table", start, t0, fs, np.round(part * 1e6).astype(np.int32), part
                    ),
                    t0,
                )
            edges = np.arange(start, stop)
            edges = edges[edges % tach_period == 0] if tach_period else edges[:0]
            recorder.add(PulseBlock("tach", start, stop, edges, edges / fs), t0)
    return path
