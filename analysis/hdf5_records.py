"""The recorder's HDF5 files (docs/recording_layout.md) as analysis ``Record`` objects.

Analysis imports nothing of the rig, so this reads the documented layout with h5py
directly (file I/O, not device I/O).  A record must be uniformly sampled: a recording
with gaps is returned as its gap-free segments, never with samples filled in; a
sweep is returned one record per step (its steady-state dwell, with its drive).
The flat file that ``impact-rig simulate --out FILE.h5`` writes is read as well.
Importing this module registers the loader for ``.h5`` and ``.hdf5`` with
:func:`analysis.records.load_record`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from analysis.exchange import meta_from_json
from analysis.records import Record, RecordFormatError, register_loader

FORMAT_NAME = "impact-rig recording"
RIG_KEYS = ("m_kg", "l_m", "R_m", "g")


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


def _channel(path: Path, f: h5py.File, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indices, times, values) of the fully stored blocks of a sampled channel."""
    try:
        group = f["channels"][name]
    except KeyError:
        raise RecordFormatError(
            f"{path}: no channel {name!r}; the recording has {list(f['channels'].keys())}"
        ) from None
    blocks = group["blocks"][()]
    # the consistent prefix of docs/recording_layout.md (format 1 files have no flags)
    stored = min(group[part].shape[0] for part in ("raw", "values", "flags") if part in group)
    blocks = blocks[blocks["stored_start"] + blocks["n_samples"] <= stored]
    n = int(blocks["stored_start"][-1] + blocks["n_samples"][-1]) if blocks.size else 0
    fs = float(group.attrs["sample_rate_hz"])
    offset = np.arange(n) - np.repeat(blocks["stored_start"], blocks["n_samples"])
    indices = np.repeat(blocks["first_index"], blocks["n_samples"]) + offset
    times = np.repeat(blocks["timestamp_s"], blocks["n_samples"]) + offset / fs
    return indices.astype(np.int64), times, group["values"][:n].astype(float)


def read_recording_arrays(path: str | Path) -> RecordingArrays:
    """The analysable content of a recording: angle, table and tach on shared sample indices."""
    path = Path(path)
    try:
        f = h5py.File(path, "r", libver="latest", swmr=True)
    except FileNotFoundError:
        raise RecordFormatError(f"{path}: file not found") from None
    except OSError as error:
        raise RecordFormatError(f"{path}: not a readable HDF5 file ({error})") from None
    with f:
        if f.attrs.get("format") != FORMAT_NAME:
            raise RecordFormatError(
                f"{path}: not an impact-rig recording (attribute 'format' is "
                f"{f.attrs.get('format')!r}; expected {FORMAT_NAME!r})"
            )
        try:
            roles = json.loads(f.attrs.get("roles_json", "{}"))
            rig_all = json.loads(f.attrs.get("rig_json", "{}"))
            drive = json.loads(f.attrs.get("drive_json", "null"))
        except json.JSONDecodeError as error:
            raise RecordFormatError(f"{path}: a metadata attribute is not JSON ({error})") from None
        angle_name = roles.get("angle", "angle")
        indices, times, angle = _channel(path, f, angle_name)
        table = None
        table_name = roles.get("table")
        if table_name and table_name in f["channels"]:
            t_indices, _, t_values = _channel(path, f, table_name)
            common, in_angle, in_table = np.intersect1d(
                indices, t_indices, assume_unique=True, return_indices=True
            )
            indices, times, angle = common, times[in_angle], angle[in_angle]
            table = t_values[in_table]
        edges = np.zeros(0, dtype=np.int64)
        tach_name = roles.get("tach")
        if tach_name and tach_name in f["pulses"]:
            group = f["pulses"][tach_name]
            stored = min(group["edge_indices"].shape[0], group["edge_times_s"].shape[0])
            covered = group["blocks"][()]
            complete = int(covered["n_edges"][np.cumsum(covered["n_edges"]) <= stored].sum())
            edges = group["edge_indices"][:complete].astype(np.int64)
        return RecordingArrays(
            indices=indices,
            time_s=times,
            angle_rad=angle,
            table_m=table,
            tach_edges=edges,
            experiment=str(f.attrs.get("experiment", "")),
            rig={key: rig_all.get(key) for key in RIG_KEYS},
            drive=drive,
            notes=str(f.attrs.get("notes", "")),
            steps=f["sweep_steps"][()],
        )


def _record(
    arrays: RecordingArrays,
    select: np.ndarray,
    path: Path,
    label: str,
    drive: dict[str, float] | None = None,
) -> Record:
    indices = arrays.indices[select]
    tach = np.flatnonzero(np.isin(indices, arrays.tach_edges))
    return Record(
        time_s=arrays.time_s[select],
        angle_rad=arrays.angle_rad[select],
        experiment=arrays.experiment,
        rig=arrays.rig,
        drive=drive if drive is not None else arrays.drive,
        table_m=None if arrays.table_m is None else arrays.table_m[select],
        tach_indices=tach,
        source=f"{path}{label}",
        notes=arrays.notes,
    )


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
        _record(arrays, slice(start, stop), path, label.format(k=k + 1))
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
            "frequency_hz": float(step["frequency_hz"]),
            "amplitude_m": float(step["amplitude_m"]),
        }
        out.append(_record(arrays, positions, path, f" step {int(step['step'])}", drive))
    return out


def _is_simulated_layout(path: Path) -> bool:
    """True for the flat file ``impact-rig simulate`` writes (no recorder 'format' attribute)."""
    try:
        with h5py.File(path, "r") as f:
            return "format" not in f.attrs and "metadata" in f.attrs and "angle_rad" in f
    except OSError:
        return False  # not found / not HDF5: read_recording_arrays says which


def load_simulated_hdf5(path: str | Path) -> Record:
    """A record from ``impact-rig simulate --out FILE.h5``: root datasets and JSON 'metadata'.

    The layout (``time_s``, ``angle_rad``, optional ``table_m`` and int8 ``tach`` at the
    root; the exchange sidecar's JSON as the root attribute ``metadata``) is documented
    in ``rig/commands/simulate.py``.
    """
    path = Path(path)
    with h5py.File(path, "r") as f:
        try:
            meta = meta_from_json(json.loads(f.attrs["metadata"]), path)
        except json.JSONDecodeError as error:
            raise RecordFormatError(f"{path}: attribute 'metadata' is not JSON ({error})") from None
        missing = [name for name in ("time_s", "angle_rad") if name not in f]
        if missing:
            raise RecordFormatError(f"{path}: no dataset {missing[0]!r} at the root")
        columns = {name: f[name][()] for name in ("time_s", "angle_rad", "table_m", "tach")
                   if name in f}
    tach = columns.get("tach")
    return Record(
        time_s=columns["time_s"],
        angle_rad=columns["angle_rad"],
        experiment=meta.experiment,
        rig=meta.rig,
        drive=meta.drive,
        table_m=columns.get("table_m"),
        tach_indices=np.zeros(0, dtype=np.int64) if tach is None else np.flatnonzero(tach > 0),
        source=str(path),
        notes=meta.notes,
    )


def load_hdf5_record(path: Path, meta_path: Path | None = None) -> Record:
    """The whole recording as one record; an error naming the gaps when it has any."""
    if meta_path is not None:
        raise RecordFormatError(
            f"{meta_path}: an HDF5 recording carries its own metadata; drop --meta"
        )
    if _is_simulated_layout(path):
        return load_simulated_hdf5(path)
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
    return _record(arrays, slice(None), path, "")


register_loader(".h5", load_hdf5_record)
register_loader(".hdf5", load_hdf5_record)
