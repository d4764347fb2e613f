"""Sweep recordings with known content, written by the project's real Recorder (real HDF5
files through the ``recording`` package), for the loaders' tests."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from rig.events import StepMark
from rig.recorder import ChannelSpec, Recorder, RecordingMetadata

RIG = {"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095, "g": 9.81}
BLOCK = 100


def write_sweep_recording(
    path: Path, angle: np.ndarray, fs: float, tach_edges: np.ndarray,
    steps: Sequence[StepMark], *, table: np.ndarray | None = None,
    lost: tuple[int, int] | None = None,
) -> Path:
    """Write ``angle`` (and ``table``) sampled at ``fs`` with tach rising edges at sample
    indices ``tach_edges`` and the sweep's step marks; ``lost`` = (start, stop) sample
    indices that never arrive (whole blocks: multiples of BLOCK)."""
    specs = [ChannelSpec("angle", "samples", "rad", fs, raw_dtype="int32")]
    if table is not None:
        specs.append(ChannelSpec("table", "samples", "m", fs, raw_dtype="int32"))
    specs.append(ChannelSpec("tach", "pulses", "", fs))
    meta = RecordingMetadata(
        experiment="forced", rig=RIG, roles={"angle": "angle", "table": "table", "tach": "tach"},
        drive={"frequency_hz": steps[0].frequency_hz, "amplitude_m": steps[0].amplitude_m},
    )
    edges_all = np.asarray(tach_edges, dtype=np.int64)
    with Recorder(path, specs, meta) as recorder:
        for mark in steps:
            recorder.add(mark, 0.0)
        lost_before = 0
        for start in range(0, angle.size, BLOCK):
            stop = min(start + BLOCK, angle.size)
            if lost is not None and lost[0] <= start < lost[1]:
                lost_before += stop - start
                continue
            t0 = start / fs
            for name, data in (("angle", angle), ("table", table)):
                if data is None:
                    continue
                part = data[start:stop]
                recorder.add(SampleBlock(name, start, t0, fs,
                                         np.round(part * 1e6).astype(np.int32), part,
                                         lost_before=lost_before), t0)
            edges = edges_all[(edges_all >= start) & (edges_all < stop)]
            recorder.add(PulseBlock("tach", start, stop, edges, edges / fs,
                                    lost_before=lost_before), t0)
            lost_before = 0
    return path


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
