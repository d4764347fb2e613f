"""Writing a recording: its layout created up front (SWMR forbids creating objects later),
then data appended and flushed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import h5py
import numpy as np

from recording.layout import (
    DRIVE_DTYPE,
    GAP_DTYPE,
    LIBVER,
    OUTAGE_DTYPE,
    PULSE_BLOCK_DTYPE,
    SAMPLE_BLOCK_DTYPE,
    STATUS_DTYPE,
    STEP_DTYPE,
    STOP_REASON_BYTES,
    TABLE_CHUNK_ROWS,
    ChannelSpec,
    RecordingStatus,
    chunk_length,
    packing,
    sample_times,
)
from recording.metadata import (
    RecordingMetadata,
    json_attribute,
    metadata_attributes,
    write_attributes,
)


class RecordingWriter:
    """Creates a recording's layout, then appends to it; SWMR-readable after every ``flush``.

    Everything is created before writing starts (SWMR forbids creating objects later).
    Data are appended before the tables that point into them, so that a reader after a
    crash keeps the rows whose samples are present.
    """

    def __init__(
        self,
        path: Path,
        channels: Sequence[ChannelSpec],
        meta: RecordingMetadata,
        *,
        software_version: str,
        compression: str | None = "auto",
    ) -> None:
        self.path = path
        self._rates = {spec.name: float(spec.sample_rate_hz) for spec in channels}
        self._kinds = {spec.name: spec.kind for spec in channels}
        self._file = h5py.File(path, "w-", libver=LIBVER)
        try:
            self._create_layout(channels, meta, software_version, compression)
        except BaseException:
            self._file.close()
            path.unlink()  # the stub holds no data: a retry must not be refused as existing
            raise

    def _create_layout(
        self,
        channels: Sequence[ChannelSpec],
        meta: RecordingMetadata,
        software_version: str,
        compression: str | None,
    ) -> None:
        f = self._file
        write_attributes(f, metadata_attributes(meta, software_version))
        samples = f.create_group("channels")
        pulses = f.create_group("pulses")
        for spec in channels:
            packed = packing(compression, spec.sample_rate_hz)
            group = (samples if spec.kind == "samples" else pulses).create_group(spec.name)
            write_attributes(
                group,
                {
                    "kind": spec.kind,
                    "unit": spec.unit,
                    "sample_rate_hz": float(spec.sample_rate_hz),
                    "device": spec.device,
                    "calibration_json": json_attribute(spec.calibration),
                },
            )
            chunk = (chunk_length(spec.sample_rate_hz),)
            if spec.kind == "samples":
                for name, dtype in (
                    ("raw", spec.raw_dtype),
                    ("values", "<f4"),
                    ("flags", "u1"),
                    ("time_s", "<f8"),
                ):
                    group.create_dataset(
                        name, (0,), maxshape=(None,), dtype=dtype, chunks=chunk, **packed
                    )
                write_attributes(
                    group["time_s"],
                    {"unit": "s", "meaning": "device time of each stored sample"},
                )
                _table(group, "blocks", SAMPLE_BLOCK_DTYPE)
            else:
                for name, dtype in (("edge_indices", "<i8"), ("edge_times_s", "<f8")):
                    group.create_dataset(
                        name, (0,), maxshape=(None,), dtype=dtype, chunks=(1024,), **packed
                    )
                _table(group, "blocks", PULSE_BLOCK_DTYPE)
            _table(group, "gaps", GAP_DTYPE)
        _table(f, "drive", DRIVE_DTYPE)
        _table(f, "sweep_steps", STEP_DTYPE)
        _table(f, "outages", OUTAGE_DTYPE)
        f.create_dataset("status", (1,), dtype=STATUS_DTYPE, chunks=(1,), fletcher32=True)
        f.swmr_mode = True

    def append_channel(
        self,
        name: str,
        columns: Mapping[str, list[np.ndarray]],
        blocks: list[tuple],
        gaps: list[tuple],
    ) -> None:
        """Append a channel's pending data: its columns (``raw``, ``values`` and ``flags``
        of a sampled channel, ``edge_indices`` and ``edge_times_s`` of a pulse channel),
        their block rows and gaps."""
        sampled = self._kinds[name] == "samples"
        group = self._file["channels" if sampled else "pulses"][name]
        for column, parts in columns.items():
            append(group[column], parts)
        block_dtype = SAMPLE_BLOCK_DTYPE if sampled else PULSE_BLOCK_DTYPE
        if sampled and blocks:
            rows = np.array(blocks, dtype=block_dtype)
            append(group["time_s"], [sample_times(rows, self._rates[name])])
        append_rows(group["blocks"], blocks, block_dtype)
        append_rows(group["gaps"], gaps, GAP_DTYPE)

    def append_drive(self, rows: list[tuple]) -> None:
        """Append drive settings (DRIVE_DTYPE rows)."""
        append_rows(self._file["drive"], rows, DRIVE_DTYPE)

    def append_steps(self, rows: list[tuple]) -> None:
        """Append sweep step marks (STEP_DTYPE rows)."""
        append_rows(self._file["sweep_steps"], rows, STEP_DTYPE)

    def append_outages(self, rows: list[tuple]) -> None:
        """Append device outages (OUTAGE_DTYPE rows: channel name as bytes first)."""
        append_rows(self._file["outages"], rows, OUTAGE_DTYPE)

    def write_status(self, status: RecordingStatus) -> None:
        """Rewrite the status row."""
        row = np.zeros(1, dtype=STATUS_DTYPE)
        row["end_host_time_s"] = status.end_host_time_s
        row["samples_written"] = status.samples_written
        row["samples_lost"] = status.samples_lost
        row["flushes"] = status.flushes
        row["closed"] = int(status.closed)
        row["stop_reason"] = status.stop_reason.encode("utf-8")[:STOP_REASON_BYTES]
        self._file["status"][0] = row[0]

    def flush(self) -> None:
        """Make everything appended visible to readers (and safe from a crash)."""
        self._file.flush()

    def close(self) -> None:
        """Release the file."""
        self._file.close()


def _table(group: h5py.Group, name: str, dtype: np.dtype) -> None:
    group.create_dataset(
        name, (0,), maxshape=(None,), dtype=dtype, chunks=(TABLE_CHUNK_ROWS,), fletcher32=True
    )


def append(dataset: h5py.Dataset, pending: list[np.ndarray]) -> None:
    """Append the pending arrays to a resizable 1-D dataset."""
    if pending:
        _extend(dataset, np.concatenate(pending))


def append_rows(dataset: h5py.Dataset, rows: list[tuple], dtype: np.dtype) -> None:
    """Append table rows (tuples in ``dtype``'s field order) to a resizable 1-D table."""
    if rows:
        _extend(dataset, np.array(rows, dtype=dtype))


def _extend(dataset: h5py.Dataset, data: np.ndarray) -> None:
    if data.size == 0:
        return
    start = dataset.shape[0]
    dataset.resize((start + data.size,))
    dataset[start:] = data

