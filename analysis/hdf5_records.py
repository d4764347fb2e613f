"""The recorder's HDF5 files (docs/recording_layout.md) as analysis ``Record`` objects.

The recording is read through :mod:`recording.reader` (which validates it and
refuses a damaged one).  A record must be uniformly sampled: a recording
with gaps is returned as its gap-free segments, never with samples filled in; a
sweep is returned one record per step (its steady-state dwell, with its drive).
:mod:`analysis.record_loaders` reads ``.h5`` and ``.hdf5`` files with :func:`load_hdf5_record`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.exchange import rig_constants
from analysis.records import Record
from recording.errors import RecordFormatError, RecordingFormatError
from recording.reader import open_recording


@dataclass(frozen=True)
class RecordingArrays:
    """The angle (and table) samples that both channels hold, with their device indices."""

    indices: np.ndarray
    time_s: np.ndarray
    angle_rad: np.ndarray
    table_m: np.ndarray | None
    tach_edges: np.ndarray  # sample indices of tach rising edges
    experiment: str
    rig: dict[str, float | None]
    drive: dict[str, float] | None
    notes: str
    steps: np.ndarray  # the /sweep_steps table
    calibrations: dict[str, Any]
    format_version: int
    stored_as: str  # the samples' dtype in the file (float32: their text needs 9 digits at most)


def read_recording_arrays(path: str | Path) -> RecordingArrays:
    """The analysable content of a recording: angle, table and tach on shared sample indices."""
    with open_recording(path) as recording:
        recording.verify()  # damage anywhere refuses the file before any of it is used
        info = recording.info
        angle_name = info.roles.get("angle", "angle")
        if angle_name not in recording.channel_names:
            raise RecordingFormatError(
                f"{path}: no channel {angle_name!r}; the recording has {recording.channel_names}"
            )
        angle_data = recording.channel(angle_name)
        indices, times, angle = (
            angle_data.indices, angle_data.times_s, angle_data.values.astype(float)
        )
        table = None
        table_name = info.roles.get("table")
        if table_name and table_name in recording.channel_names:
            table_data = recording.channel(table_name)
            common, in_angle, in_table = np.intersect1d(
                indices, table_data.indices, assume_unique=True, return_indices=True
            )
            indices, times, angle = common, times[in_angle], angle[in_angle]
            table = table_data.values.astype(float)[in_table]
        edges = np.zeros(0, dtype=np.int64)
        tach_name = info.roles.get("tach")
        if tach_name and tach_name in recording.pulse_names:
            edges = recording.pulses(tach_name).edge_indices.astype(np.int64)
        return RecordingArrays(
            indices=indices,
            time_s=times,
            angle_rad=angle,
            table_m=table,
            tach_edges=edges,
            experiment=info.experiment,
            rig=rig_constants(info.rig),
            drive=info.drive,
            notes=info.notes,
            steps=recording.sweep_steps(),
            calibrations=dict(info.calibrations),
            format_version=int(info.format_version),
            stored_as=angle_data.values.dtype.name,
        )


def stretch_record(
    arrays: RecordingArrays,
    select: np.ndarray,
    path: Path,
    label: str,
    drive: dict[str, float] | None = None,
) -> Record:
    """Samples ``select`` of the recording as a record (labelled ``label`` after the path),
    with ``drive``, or else the drive every sweep step in it shares and the steps listed."""
    indices = arrays.indices[select]
    tach = np.flatnonzero(np.isin(indices, arrays.tach_edges))
    context: dict[str, Any] = {"calibrations": arrays.calibrations,
                               "recording_format_version": arrays.format_version,
                               "samples_stored_as": arrays.stored_as}
    if drive is None:
        drive, steps = _whole_drive(arrays, indices)
        if steps:
            context["sweep_steps"] = steps
    return Record(
        time_s=arrays.time_s[select],
        angle_rad=arrays.angle_rad[select],
        experiment=arrays.experiment,
        rig=arrays.rig,
        drive=drive,
        table_m=None if arrays.table_m is None else arrays.table_m[select],
        tach_indices=tach,
        source=f"{path}{label}",
        notes=arrays.notes,
        context=context,
    )


def _whole_drive(
    arrays: RecordingArrays, indices: np.ndarray
) -> tuple[dict[str, float] | None, list[dict[str, Any]]]:
    """The drive of a stretch that may span sweep steps, and those steps.  Only what every
    step in it shares is its drive: a frequency sweep's stretch has no one frequency (the
    recording's own drive is where the sweep began), and a reader must not take one."""
    steps = arrays.steps
    if steps.size and indices.size:
        steps = steps[(steps["dwell_end_index"] > indices[0])
                      & (steps["settle_start_index"] <= indices[-1])]
    if not steps.size:
        return arrays.drive, []
    listed = [{"step": int(s["step"]), "direction": int(s["direction"]),
               q.frequency_hz: float(s[q.frequency_hz]),
               q.amplitude_m: float(s[q.amplitude_m]),
               "start_s": _time_at(arrays, int(s["settle_start_index"])),
               "dwell_start_s": _time_at(arrays, int(s["dwell_start_index"])),
               "dwell_end_s": _time_at(arrays, int(s["dwell_end_index"])),
               "complete": bool(s["complete"])} for s in steps]
    shared = {key: listed[0][key] for key in (q.frequency_hz, q.amplitude_m)
              if len({step[key] for step in listed}) == 1}
    return shared or None, listed


def _time_at(arrays: RecordingArrays, index: int) -> float:
    """The time of device sample ``index`` (the nearest recorded one)."""
    at = min(int(np.searchsorted(arrays.indices, index)), arrays.indices.size - 1)
    return float(arrays.time_s[at] + (index - arrays.indices[at]) * _sample_step(arrays))


def _sample_step(arrays: RecordingArrays) -> float:
    if arrays.indices.size < 2:
        return 0.0
    return float((arrays.time_s[-1] - arrays.time_s[0]) / (arrays.indices[-1] - arrays.indices[0]))


def gap_free_segments(indices: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) positions of the runs of consecutive sample indices."""
    if indices.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(indices) != 1) + 1
    starts = np.concatenate(([0], breaks))
    stops = np.concatenate((breaks, [indices.size]))
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def load_hdf5_segments(path: str | Path) -> list[Record]:
    """One record per gap-free stretch of the recording (one record when nothing was lost)."""
    path = Path(path)
    arrays = read_recording_arrays(path)
    segments = gap_free_segments(arrays.indices)
    if not segments:
        raise RecordFormatError(f"{path}: the recording holds no samples")
    label = "" if len(segments) == 1 else " segment {k}"
    return [
        stretch_record(arrays, slice(start, stop), path, label.format(k=k + 1))
        for k, (start, stop) in enumerate(segments)
    ]


def load_hdf5_steps(path: str | Path) -> list[Record]:
    """One record per complete sweep step: its dwell, with the step's drive setting."""
    path = Path(path)
    arrays = read_recording_arrays(path)
    steps = arrays.steps[arrays.steps["complete"] == 1] if arrays.steps.size else arrays.steps
    if steps.size == 0:
        raise RecordFormatError(f"{path}: the recording has no complete sweep steps")
    out = []
    for step in steps:
        select = (arrays.indices >= step["dwell_start_index"]) & (
            arrays.indices < step["dwell_end_index"]
        )
        positions = np.flatnonzero(select)
        if positions.size < 2 or np.any(np.diff(arrays.indices[positions]) != 1):
            raise RecordFormatError(
                f"{path}: sweep step {int(step['step'])} has lost samples in its dwell; "
                "export the gap-free segments instead"
            )
        drive = {
            q.frequency_hz: float(step[q.frequency_hz]),
            q.amplitude_m: float(step[q.amplitude_m]),
        }
        out.append(stretch_record(arrays, positions, path, f" step {int(step['step'])}", drive))
    return out


def load_hdf5_record(path: Path, meta_path: Path | None = None) -> Record:
    """The whole recording as one record; an error naming the gaps when it has any."""
    if meta_path is not None:
        raise RecordFormatError(
            f"{meta_path}: an HDF5 recording carries its own metadata; drop --meta"
        )
    arrays = read_recording_arrays(path)
    segments = gap_free_segments(arrays.indices)
    if not segments:
        raise RecordFormatError(f"{path}: the recording holds no samples")
    if len(segments) > 1:
        first_gap = arrays.indices[segments[0][1] - 1] + 1
        raise RecordFormatError(
            f"{path}: {len(segments) - 1} gap(s) in the samples (the first at sample "
            f"{first_gap}); analyse one gap-free segment ('impact-rig export --gaps split')"
        )
    return stretch_record(arrays, slice(None), path, "")
