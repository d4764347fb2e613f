"""The recording's HDF5 layout (docs/recording_layout.md): the one module that writes and reads it.

The recorder (``rig.recorder``) writes through :class:`RecordingWriter`; the replay
drivers, the GUI and the analysis loaders read through :class:`Recording`.  Every
chunk carries a fletcher32 checksum and every piece of metadata HDF5's own, so a
damaged file is a read error, never data.  Opening checks, before HDF5 sees the
file, that it is whole (a truncated file sends an HDF5 SWMR reader into minutes of
silent retries), then checks ``format``, ``format_version``, the datasets, their
dtypes and lengths and the block times.  Files are written in the HDF5 1.10 file
format (SWMR needs at least that), which every HDF5 since 1.10 reads.
"""

from __future__ import annotations

import json
import math
import os
import struct
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.hdf5_library import set_metadata_read_attempts
from analysis.json_output import to_json_text
from analysis.records import RecordFormatError

FORMAT_NAME = "impact-rig recording"
FORMAT_VERSION = 3  # 3: time_s per sample, fletcher32 checksums, provenance
READABLE_VERSIONS = (1, 2, 3)  # 1: no flags; 2: flags; 3: time_s and provenance
LIBVER = ("v110", "v110")  # SWMR needs the 1.10 format; nothing newer, so HDF5 1.10+ reads it
STOP_REASON_BYTES = 256
FAST_CHANNEL_HZ = 50_000.0  # above this rate channels are compressed with lzf, not gzip
TABLE_CHUNK_ROWS = 256

SAMPLE_BLOCK_DTYPE = np.dtype(
    [
        ("first_index", "<i8"),
        ("n_samples", "<i8"),
        ("stored_start", "<i8"),
        ("timestamp_s", "<f8"),
        ("host_time_s", "<f8"),
        ("lost_before", "<i8"),
    ]
)
PULSE_BLOCK_DTYPE = np.dtype(
    [
        ("first_index", "<i8"),
        ("end_index", "<i8"),
        ("host_time_s", "<f8"),
        ("lost_before", "<i8"),
        ("n_edges", "<i8"),
    ]
)
GAP_DTYPE = np.dtype([("start_index", "<i8"), ("length", "<i8")])
DRIVE_DTYPE = np.dtype(
    [
        ("host_time_s", "<f8"),
        ("sample_index", "<i8"),
        ("frequency_hz", "<f8"),
        ("amplitude_m", "<f8"),
        ("enabled", "u1"),
        ("source", "u1"),
    ]
)
STEP_DTYPE = np.dtype(
    [
        ("step", "<i4"),
        ("direction", "i1"),
        ("frequency_hz", "<f8"),
        ("amplitude_m", "<f8"),
        ("settle_start_index", "<i8"),
        ("dwell_start_index", "<i8"),
        ("dwell_end_index", "<i8"),
        ("complete", "u1"),
    ]
)
STATUS_DTYPE = np.dtype(
    [
        ("end_host_time_s", "<f8"),
        ("samples_written", "<i8"),
        ("samples_lost", "<i8"),
        ("flushes", "<i8"),
        ("closed", "u1"),
        ("stop_reason", f"S{STOP_REASON_BYTES}"),
    ]
)
OUTAGE_CHANNEL_BYTES = 64
OUTAGE_DTYPE = np.dtype(
    [
        ("channel", f"S{OUTAGE_CHANNEL_BYTES}"),
        ("start_index", "<i8"),
        ("length", "<i8"),
        ("outage_s", "<f8"),
        ("host_time_s", "<f8"),
    ]
)
ROOT_TABLES = {"drive": DRIVE_DTYPE, "sweep_steps": STEP_DTYPE, "status": STATUS_DTYPE}
# added within format version 3: a file written before it has none (read as empty)
OPTIONAL_ROOT_TABLES = {"outages": OUTAGE_DTYPE}
REPAIR_HINT = "'impact-rig repair {path}' recovers what can still be read"
# A SWMR reader's retries of a metadata block sleep 1 ns, 2 ns, 4 ns, ...: 30 attempts wait
# about a second in all (a live writer's flush takes milliseconds), 36 over a minute.
SWMR_METADATA_READ_ATTEMPTS = 30


class RecordingFormatError(RecordFormatError):
    """The file is not a readable impact-rig recording; the message names the file and the part."""


class RecordingDamagedError(RecordingFormatError):
    """The file is a recording, but truncated or with damaged bytes (checksum failures)."""


# -- what a recording holds ------------------------------------------------------------------


@dataclass(frozen=True)
class ChannelSpec:
    """One channel to record: ``kind`` is 'samples' (SampleBlock) or 'pulses' (PulseBlock)."""

    name: str
    kind: str = "samples"
    unit: str = ""
    sample_rate_hz: float = 0.0
    device: str = ""
    calibration: dict[str, Any] | None = None
    raw_dtype: str = "int32"

    def __post_init__(self) -> None:
        if self.kind not in ("samples", "pulses"):
            raise ValueError(
                f"channel {self.name!r}: kind is {self.kind!r}; expected 'samples' or 'pulses'"
            )
        if not self.name or "/" in self.name:
            raise ValueError(f"channel name {self.name!r} must be non-empty and contain no '/'")
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise ValueError(
                f"channel {self.name!r}: sample_rate_hz is {self.sample_rate_hz!r}; expected a "
                "positive number of Hz"
            )


@dataclass(frozen=True)
class RecordingMetadata:
    """What a recording must carry to be analysed years later (root attributes of the file)."""

    experiment: str
    notes: str = ""
    rig: dict[str, float | None] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    devices: dict[str, Any] = field(default_factory=dict)
    config_toml: str = ""
    drive: dict[str, float] | None = None
    roles: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    start_time_utc: str = ""
    provenance: dict[str, Any] = field(default_factory=dict)  # analysis.provenance


@dataclass(frozen=True)
class RecordingInfo(RecordingMetadata):
    """The recording's metadata (root attributes), decoded, with the software and format
    version that wrote it."""

    software_version: str = ""
    format_version: int = 0


@dataclass(frozen=True)
class RecordingStatus:
    """Running totals of the writer; ``closed`` is False for a file cut short or still open."""

    end_host_time_s: float
    samples_written: int
    samples_lost: int
    flushes: int
    closed: bool
    stop_reason: str


@dataclass(frozen=True)
class ChannelData:
    """All stored samples of one channel with their device indices and times."""

    name: str
    unit: str
    sample_rate_hz: float
    indices: np.ndarray  # int64 device sample index of every stored sample
    times_s: np.ndarray  # device time of every stored sample
    raw: np.ndarray
    values: np.ndarray
    flags: np.ndarray  # uint8 status bits per sample (drivers.sensors.FLAG_*); 0: good
    gaps: np.ndarray  # structured: start_index, length

    def __len__(self) -> int:
        return int(self.values.size)


@dataclass(frozen=True)
class PulseData:
    """Tachometer edges of one pulse channel and the index range the stream covered."""

    name: str
    edge_indices: np.ndarray
    edge_times_s: np.ndarray
    covered: np.ndarray  # structured blocks: first_index, end_index, ...
    gaps: np.ndarray


# -- the container: whole, and in which mode to open it ----------------------------------------

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_WRITER_FLAGS = 0x01 | 0x04  # superblock consistency flags: open for writing / SWMR writing


@dataclass(frozen=True)
class Superblock:
    """The parts of the HDF5 superblock (version 2 or 3) that say whether a file is whole."""

    version: int
    flags: int  # non-zero while a writer has the file open (or died with it open)
    stored_eof: int  # the file's size as its writer last recorded it
    size: int  # the file's size on disk


def read_superblock(path: Path) -> Superblock:
    """The superblock of the HDF5 file ``path``; RecordingFormatError when it is none."""
    try:
        with path.open("rb") as handle:
            head = handle.read(48)
            size = os.fstat(handle.fileno()).st_size
    except FileNotFoundError:
        raise RecordingFormatError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise RecordingFormatError(f"{path}: is a folder, not a recording") from None
    except OSError as error:
        raise RecordingFormatError(f"{path}: cannot be read ({error.strerror})") from None
    if not head.startswith(HDF5_SIGNATURE):
        raise RecordingFormatError(
            f"{path}: not an HDF5 file (it does not start with the HDF5 signature)"
        )
    if len(head) < 48:
        raise RecordingDamagedError(
            f"{path}: truncated to {size} bytes, too short for an HDF5 superblock"
        )
    version = head[8]
    if version in (2, 3):
        flags = head[11]
        (eof,) = struct.unpack_from("<Q", head, 28)
    elif version in (0, 1):  # files of other HDF5 writers: no consistency flags
        flags = 0
        (eof,) = struct.unpack_from("<Q", head, 40 if version == 0 else 44)
    else:
        raise RecordingFormatError(f"{path}: HDF5 superblock version {version} is not supported")
    return Superblock(version, flags, eof, size)


def check_whole(path: Path, waits_s: Sequence[float] = (0.3, 0.6)) -> Superblock:
    """The superblock of a file that is as long as its writer said; RecordingDamagedError if not.

    A live SWMR writer may have reserved space it has not yet written, so a short file
    whose writer flags are set is looked at again after ``waits_s`` before it is refused.
    """
    block = read_superblock(path)
    for wait_s in waits_s:
        if block.size >= block.stored_eof or not block.flags & _WRITER_FLAGS:
            break
        time.sleep(wait_s)
        block = read_superblock(path)
    if block.size < block.stored_eof:
        raise RecordingDamagedError(
            f"{path}: truncated: {block.size} of its {block.stored_eof} bytes are present; "
            + REPAIR_HINT.format(path=path)
        )
    return block


def open_hdf5(path: str | Path) -> h5py.File:
    """A recording file opened read-only: SWMR while a writer has it (or died with it) open.

    A cleanly closed file is opened without SWMR, where a checksum failure is an error at
    once (SWMR readers retry each one for a long time, in case a writer is mid-flush).
    """
    path = Path(path)
    block = check_whole(path)
    live = bool(block.flags & _WRITER_FLAGS)
    try:
        if live:
            return h5py.File(_open_swmr_reader(path))
        return h5py.File(path, "r")
    except (OSError, RuntimeError) as error:  # RuntimeError: a superblock HDF5 cannot decode
        raise RecordingDamagedError(
            f"{path}: HDF5 cannot open it ({_first_line(error)}); " + REPAIR_HINT.format(path=path)
        ) from None


def _open_swmr_reader(path: Path) -> h5py.h5f.FileID:
    """``path`` opened read-only for SWMR, with metadata checksum failures retried for about
    a second at most (the library's default retries a damaged block for days)."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_LATEST)
    set_metadata_read_attempts(fapl, SWMR_METADATA_READ_ATTEMPTS)
    return h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl)


def _first_line(error: BaseException) -> str:
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__


# -- writing ----------------------------------------------------------------------------------


def chunk_length(sample_rate_hz: float) -> int:
    """About one second of samples per chunk, between 4096 and 65536 elements."""
    target = max(4096, min(65536, int(sample_rate_hz)))
    return 1 << (target - 1).bit_length() if target < 65536 else 65536


def packing(compression: str | None, sample_rate_hz: float) -> dict[str, Any]:
    """Filters of a channel's datasets.  'auto': gzip level 1 (readable by every HDF5 tool)
    up to FAST_CHANNEL_HZ, lzf above it (2-3 times less CPU for ~10 % more bytes).  Every
    chunk carries a fletcher32 checksum, so damage is a read error, not data."""
    if compression == "auto":
        compression = "lzf" if sample_rate_hz > FAST_CHANNEL_HZ else "gzip"
    if compression not in ("gzip", "lzf", None):
        raise ValueError(f"compression {compression!r}; expected 'auto', 'gzip', 'lzf' or None")
    packed: dict[str, Any] = {
        "compression": compression,
        "shuffle": compression is not None,
        "fletcher32": True,
    }
    if compression == "gzip":
        packed["compression_opts"] = 1
    return packed


def metadata_attributes(meta: RecordingMetadata, software_version: str) -> dict[str, Any]:
    """The root attributes that hold ``meta`` (docs/recording_layout.md, "Root attributes")."""
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "software_version": software_version,
        "start_time_utc": meta.start_time_utc,
        "experiment": meta.experiment,
        "notes": meta.notes,
        "rig_json": to_json_text(meta.rig, one_line=True),
        "calibrations_json": to_json_text(meta.calibrations, one_line=True),
        "devices_json": to_json_text(meta.devices, one_line=True),
        "config_toml": meta.config_toml,
        "drive_json": to_json_text(meta.drive, one_line=True),
        "roles_json": to_json_text(meta.roles, one_line=True),
        "extra_json": to_json_text(meta.extra, one_line=True),
        "provenance_json": to_json_text(meta.provenance, one_line=True),
    }


def write_attributes(node: h5py.HLObject, values: dict[str, Any]) -> None:
    """Set ``node``'s attributes, text as fixed-length UTF-8 strings.  Those are kept with the
    attribute itself, under HDF5's metadata checksums; a variable-length string lives in the
    global heap, which has none (zeroed bytes there sent HDF5 into an endless loop)."""
    for key, value in values.items():
        if isinstance(value, str):
            data = value.encode("utf-8")
            node.attrs.create(key, data, dtype=h5py.string_dtype("utf-8", max(1, len(data))))
        else:
            node.attrs[key] = value


def read_attributes(node: h5py.HLObject) -> dict[str, Any]:
    """``node``'s attributes, text as ``str`` whether stored fixed-length or variable-length."""
    return {
        key: value.decode("utf-8", "replace") if isinstance(value, bytes) else value
        for key, value in node.attrs.items()
    }


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
                    "calibration_json": to_json_text(spec.calibration, one_line=True),
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


def sample_times(rows: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """Device time of every sample of the block rows: timestamp_s + k / fs within a block."""
    counts = rows["n_samples"].astype(np.int64)
    offset = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(rows["timestamp_s"], counts) + offset / sample_rate_hz


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


# -- reading ----------------------------------------------------------------------------------


class Recording:
    """An open, validated recording; ``refresh()`` shows what a live writer flushed since.

    Everything returned is the file's consistent prefix: block rows whose samples are
    all present, edges inside complete pulse blocks.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open_hdf5(self.path)
        try:
            self.info = self._check_layout()
        except (OSError, RuntimeError, KeyError) as error:  # HDF5 cannot read an attribute
            self._file.close()
            raise self._damaged("the layout", error) from None
        except BaseException:
            self._file.close()
            raise

    # -- validation ---------------------------------------------------------------------------

    def _fail(self, what: str) -> RecordingFormatError:
        return RecordingFormatError(f"{self.path}: {what}")

    def _check_layout(self) -> RecordingInfo:
        try:
            attrs = read_attributes(self._file)
        except (OSError, RuntimeError, KeyError) as error:
            raise self._damaged("/", error) from None
        if attrs.get("format") != FORMAT_NAME:
            raise self._fail(
                f"attribute 'format' is {attrs.get('format')!r}; expected {FORMAT_NAME!r} "
                "(not an impact-rig recording)"
            )
        version = attrs.get("format_version")
        if isinstance(version, np.integer):
            version = int(version)
        if not isinstance(version, int) or version not in READABLE_VERSIONS:
            raise self._fail(
                f"format_version is {version!r}; this software reads versions "
                f"{', '.join(map(str, READABLE_VERSIONS))} (a newer impact-rig may read it)"
            )
        self.format_version = version
        for top in ("channels", "pulses"):
            if not isinstance(self._node(top), h5py.Group):
                raise self._fail(f"/{top} is not a group")
        self._check_root_tables()
        for name in self.channel_names:
            group = self._node(f"channels/{name}")
            self._check_channel_attrs(group)
            needed = ["raw", "values"] + (["flags"] if version >= 2 else [])
            needed += ["time_s"] if version >= 3 else []
            for part in needed:
                self._node(f"channels/{name}/{part}")
            if group["raw"].dtype.kind not in "iu":
                raise self._fail(f"{group['raw'].name} has dtype {group['raw'].dtype}; expected "
                                 "integer ADC counts")
            for part, kinds in (("values", "f"), ("flags", "u"), ("time_s", "f")):
                if part in group and group[part].dtype.kind not in kinds:
                    raise self._fail(f"{group[part].name} has dtype {group[part].dtype}")
            self._check_dataset(self._node(f"channels/{name}/blocks"), SAMPLE_BLOCK_DTYPE)
            self._check_dataset(self._node(f"channels/{name}/gaps"), GAP_DTYPE)
        for name in self.pulse_names:
            group = self._node(f"pulses/{name}")
            self._check_channel_attrs(group)
            for part in ("edge_indices", "edge_times_s"):
                self._node(f"pulses/{name}/{part}")
            self._check_dataset(self._node(f"pulses/{name}/blocks"), PULSE_BLOCK_DTYPE)
            self._check_dataset(self._node(f"pulses/{name}/gaps"), GAP_DTYPE)
        return RecordingInfo(
            experiment=str(attrs.get("experiment", "")),
            notes=str(attrs.get("notes", "")),
            start_time_utc=str(attrs.get("start_time_utc", "")),
            software_version=str(attrs.get("software_version", "")),
            format_version=version,
            rig=self._json(attrs, "rig_json", {}),
            calibrations=self._json(attrs, "calibrations_json", {}),
            devices=self._json(attrs, "devices_json", {}),
            config_toml=str(attrs.get("config_toml", "")),
            drive=self._json(attrs, "drive_json", None),
            roles=self._json(attrs, "roles_json", {}),
            extra=self._json(attrs, "extra_json", {}),
            provenance=self._json(attrs, "provenance_json", {}),
        )

    def _check_root_tables(self) -> None:
        for name, dtype in ROOT_TABLES.items():
            self._check_dataset(self._node(name), dtype)
        for name, dtype in OPTIONAL_ROOT_TABLES.items():
            if name in self._file:
                self._check_dataset(self._node(name), dtype)

    def _node(self, name: str) -> Any:
        """The object at ``name``: missing is a format error, present but unreadable (h5py
        says KeyError for both) is damage."""
        try:
            if name in self._file:
                return self._file[name]
        except (OSError, RuntimeError, KeyError) as error:
            raise self._damaged(f"/{name}", error) from None
        raise self._fail(f"no /{name} (docs/recording_layout.md)")

    def _check_dataset(self, dataset: Any, dtype: np.dtype) -> None:
        if not isinstance(dataset, h5py.Dataset) or dataset.ndim != 1:
            raise self._fail(f"{getattr(dataset, 'name', dataset)} is not a 1-D table")
        missing = [name for name in dtype.names if name not in (dataset.dtype.names or ())]
        if missing:
            raise self._fail(f"{dataset.name} lacks the field(s) {', '.join(missing)}")

    def _check_channel_attrs(self, group: h5py.Group) -> None:
        attrs = read_attributes(group)
        missing = [key for key in ("sample_rate_hz", "unit") if key not in attrs]
        if missing:
            raise self._fail(f"{group.name} has no attribute '{missing[0]}'")
        try:
            rate = float(attrs["sample_rate_hz"])
        except (TypeError, ValueError):
            raise self._fail(f"{group.name}: attribute sample_rate_hz is not a number") from None
        if not (math.isfinite(rate) and rate > 0):
            raise self._fail(f"{group.name}: sample_rate_hz is {rate}; expected a positive rate")

    def _json(self, attrs: dict[str, Any], key: str, default: Any) -> Any:
        text = attrs.get(key)
        if text is None:
            return default
        try:
            return json.loads(text)
        except (json.JSONDecodeError, TypeError) as error:
            raise self._fail(f"attribute {key!r} is not JSON ({error})") from None

    def _damaged(self, where: str, error: BaseException) -> RecordingDamagedError:
        return RecordingDamagedError(
            f"{self.path}: {where} is damaged ({_first_line(error)}); "
            + REPAIR_HINT.format(path=self.path)
        )

    def read(self, dataset: h5py.Dataset, selection: Any = ()) -> np.ndarray:
        """``dataset[selection]``; a checksum or decoding failure becomes RecordingDamagedError."""
        try:
            return dataset[selection]
        except (OSError, RuntimeError) as error:
            raise self._damaged(dataset.name, error) from None

    # -- structure ----------------------------------------------------------------------------

    @property
    def channel_names(self) -> list[str]:
        """Sampled channels (angle, table, ...)."""
        return list(self._node("channels").keys())

    @property
    def pulse_names(self) -> list[str]:
        """Pulse channels (the tachometer)."""
        return list(self._node("pulses").keys())

    def refresh(self) -> None:
        """See data a live writer flushed since the file was opened (SWMR)."""
        if not self._file.swmr_mode:
            return
        for obj in self._datasets():
            obj.refresh()

    def _datasets(self) -> Iterator[h5py.Dataset]:
        for top in ("channels", "pulses"):
            for group in self._file[top].values():
                yield from (d for d in group.values() if isinstance(d, h5py.Dataset))
        for name in ROOT_TABLES:
            yield self._file[name]
        for name in OPTIONAL_ROOT_TABLES:
            if name in self._file:
                yield self._file[name]

    def _group(self, top: str, name: str) -> h5py.Group:
        try:
            return self._file[top][name]
        except KeyError:
            names = list(self._file[top].keys())
            raise self._fail(f"no {top[:-1]} named {name!r}; the file has {names}") from None

    def _top(self, name: str) -> str:
        """'channels' or 'pulses', whichever holds ``name`` (an error naming all otherwise)."""
        if name in self.channel_names:
            return "channels"
        if name in self.pulse_names:
            return "pulses"
        raise self._fail(
            f"no channel {name!r}; the file has {self.channel_names + self.pulse_names}"
        )

    def sample_rate_hz(self, name: str) -> float:
        """The nominal sample rate of a sampled or pulse channel."""
        return float(self._group(self._top(name), name).attrs["sample_rate_hz"])

    def unit(self, name: str) -> str:
        """The SI unit of a channel's calibrated values ('' for pulse channels)."""
        return str(read_attributes(self._group(self._top(name), name))["unit"])

    def channel_dtype(self, name: str) -> np.dtype:
        """The stored dtype of a sampled channel's raw counts."""
        return self._group("channels", name)["raw"].dtype

    def role(self, role: str) -> str | None:
        """The channel playing ``role`` ('angle', 'table', 'tach'), or None."""
        return self.info.roles.get(role)

    # -- data ---------------------------------------------------------------------------------

    def _stored(self, group: h5py.Group) -> int:
        parts = [p for p in ("raw", "values", "flags", "time_s") if p in group]
        return min(group[part].shape[0] for part in parts)

    def complete_blocks(self, name: str) -> np.ndarray:
        """Rows of a sampled channel's block table whose samples are fully stored (validated:
        positive counts, contiguous storage, finite and increasing device times and indices)."""
        group = self._group("channels", name)
        blocks = self.read(group["blocks"])
        if self._file.swmr_mode:
            # a live writer's table can show its new rows' extent before their contents
            # (zeros: a reader refreshed between the two); such trailing rows are in flight
            written = np.flatnonzero(blocks["n_samples"] != 0)
            blocks = blocks[:written[-1] + 1 if written.size else 0]
        blocks = blocks[blocks["stored_start"] + blocks["n_samples"] <= self._stored(group)]
        self._check_blocks(group["blocks"].name, blocks)
        return blocks

    def _check_blocks(self, where: str, blocks: np.ndarray) -> None:
        if blocks.size == 0:
            return
        n = blocks["n_samples"]
        starts = np.concatenate(([0], np.cumsum(n)[:-1]))
        problems = [
            (n <= 0, "n_samples is not positive"),
            (blocks["stored_start"] != starts, "stored_start does not follow the rows before"),
            (~np.isfinite(blocks["timestamp_s"]), "timestamp_s is not a finite number"),
        ]
        later = np.concatenate(([True], np.diff(blocks["timestamp_s"]) > 0))
        after = np.concatenate(
            ([True], blocks["first_index"][1:] >= blocks["first_index"][:-1] + n[:-1])
        )
        problems += [
            (~later, "timestamp_s does not increase"),
            (~after, "first_index overlaps the block before"),
            (blocks["first_index"] < 0, "first_index is negative"),
        ]
        for bad, what in problems:
            rows = np.flatnonzero(bad)
            if rows.size:
                row = int(rows[0])
                raise self._fail(
                    f"{where} row {row}: {what} (first_index {int(blocks['first_index'][row])}, "
                    f"timestamp_s {float(blocks['timestamp_s'][row])!r})"
                )

    def verify(self, slab: int = 1 << 20) -> None:
        """Read every stored byte once, so that damage anywhere (checksums) is an error now,
        before any of the file is used."""
        for dataset in self._datasets():
            for start in range(0, dataset.shape[0], slab):
                self.read(dataset, np.s_[start : start + slab])
        for name in self.channel_names:
            group = self._file["channels"][name]
            if "time_s" in group:  # the stored times agree with the block table
                blocks = self.complete_blocks(name)
                expected = sample_times(blocks, float(group.attrs["sample_rate_hz"]))
                stored = self.read(group["time_s"], np.s_[: expected.size])
                if not np.allclose(stored, expected, rtol=0, atol=1e-9, equal_nan=False):
                    row = int(np.flatnonzero(~np.isclose(stored, expected, rtol=0, atol=1e-9))[0])
                    raise self._fail(f"{group['time_s'].name}[{row}] disagrees with the blocks")

    def read_samples(self, name: str, start: int, stop: int) -> tuple[np.ndarray, ...]:
        """(raw, values, flags) of stored samples [start, stop) of a sampled channel."""
        group = self._group("channels", name)
        raw = self.read(group["raw"], np.s_[start:stop])
        values = self.read(group["values"], np.s_[start:stop])
        if "flags" in group:
            flags = self.read(group["flags"], np.s_[start:stop])
        else:  # format 1: every sample good
            flags = np.zeros(raw.size, dtype=np.uint8)
        return raw, values, flags

    def channel(self, name: str) -> ChannelData:
        """All stored samples of a sampled channel (the consistent prefix)."""
        group = self._group("channels", name)
        blocks = self.complete_blocks(name)
        n = int(blocks["stored_start"][-1] + blocks["n_samples"][-1]) if blocks.size else 0
        fs = float(group.attrs["sample_rate_hz"])
        offset_in_block = np.arange(n) - np.repeat(blocks["stored_start"], blocks["n_samples"])
        indices = np.repeat(blocks["first_index"], blocks["n_samples"]) + offset_in_block
        raw, values, flags = self.read_samples(name, 0, n)
        last = int(indices[-1]) + 1 if n else None
        gaps = self.read(group["gaps"])
        if last is not None:
            gaps = gaps[gaps["start_index"] < last]
        return ChannelData(
            name=name,
            unit=str(read_attributes(group)["unit"]),
            sample_rate_hz=fs,
            indices=indices.astype(np.int64),
            times_s=sample_times(blocks, fs),
            raw=raw,
            values=values,
            flags=flags,
            gaps=gaps,
        )

    def pulses(self, name: str) -> PulseData:
        """Edges of a pulse channel inside its fully stored blocks."""
        group = self._group("pulses", name)
        blocks = self.read(group["blocks"])
        stored = min(group["edge_indices"].shape[0], group["edge_times_s"].shape[0])
        blocks = blocks[np.cumsum(blocks["n_edges"]) <= stored]
        n = int(blocks["n_edges"].sum())
        edges = self.read(group["edge_indices"], np.s_[:n])
        times = self.read(group["edge_times_s"], np.s_[:n])
        if n and not (np.all(np.isfinite(times)) and np.all(np.diff(edges) > 0)):
            raise self._fail(f"{group.name}: edge times not finite or edges not increasing")
        return PulseData(
            name=name,
            edge_indices=edges,
            edge_times_s=times,
            covered=blocks,
            gaps=self.read(group["gaps"]),
        )

    def drive_log(self) -> np.ndarray:
        """Drive settings over time (structured: host_time_s, sample_index, frequency_hz, ...)."""
        return self.read(self._file["drive"])

    def sweep_steps(self) -> np.ndarray:
        """Sweep step marks (structured: step, direction, frequency_hz, amplitude_m, ...)."""
        return self.read(self._file["sweep_steps"])

    def outages(self) -> np.ndarray:
        """Times a device went away and came back (structured: channel, start_index, length,
        outage_s, host_time_s); each is also in its channel's gaps.  Empty for files
        written before outages were recorded."""
        if "outages" not in self._file:
            return np.zeros(0, OUTAGE_DTYPE)
        return self.read(self._file["outages"])

    def status(self) -> RecordingStatus:
        """The writer's running totals as of its last flush."""
        row = self.read(self._file["status"], 0)
        return RecordingStatus(
            end_host_time_s=float(row["end_host_time_s"]),
            samples_written=int(row["samples_written"]),
            samples_lost=int(row["samples_lost"]),
            flushes=int(row["flushes"]),
            closed=bool(row["closed"]),
            stop_reason=bytes(row["stop_reason"]).rstrip(b"\0").decode("utf-8", "replace"),
        )

    def close(self) -> None:
        """Release the file."""
        self._file.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def open_recording(path: str | Path) -> Recording:
    """Open a recording read-only, validating that it is one and that it is whole."""
    return Recording(path)


# -- repair -----------------------------------------------------------------------------------

_M32 = 0xFFFFFFFF
SUPERBLOCK_V2_BYTES = 48  # version 2/3 superblock with 8-byte addresses, checksum last


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _M32


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle``: the checksum HDF5 puts on its metadata."""
    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & _M32
    k = 0
    while length > 12:
        a = (a + int.from_bytes(data[k : k + 4], "little")) & _M32
        b = (b + int.from_bytes(data[k + 4 : k + 8], "little")) & _M32
        c = (c + int.from_bytes(data[k + 8 : k + 12], "little")) & _M32
        a = ((a - c) & _M32) ^ _rot(c, 4); c = (c + b) & _M32  # noqa: E702
        b = ((b - a) & _M32) ^ _rot(a, 6); a = (a + c) & _M32  # noqa: E702
        c = ((c - b) & _M32) ^ _rot(b, 8); b = (b + a) & _M32  # noqa: E702
        a = ((a - c) & _M32) ^ _rot(c, 16); c = (c + b) & _M32  # noqa: E702
        b = ((b - a) & _M32) ^ _rot(a, 19); a = (a + c) & _M32  # noqa: E702
        c = ((c - b) & _M32) ^ _rot(b, 4); b = (b + a) & _M32  # noqa: E702
        length -= 12
        k += 12
    if length == 0:
        return c
    tail = data[k:] + bytes(12 - length)
    a = (a + int.from_bytes(tail[0:4], "little")) & _M32
    b = (b + int.from_bytes(tail[4:8], "little")) & _M32
    c = (c + int.from_bytes(tail[8:12], "little")) & _M32
    c ^= b; c = (c - _rot(b, 14)) & _M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 11)) & _M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _M32  # noqa: E702
    return c


def clear_writer_flags(path: Path) -> None:
    """What ``h5clear -s`` does: mark the file as closed by its writer (superblock version 2
    or 3), so that tools without SWMR open a file whose writer was killed."""
    with path.open("r+b") as handle:
        head = bytearray(handle.read(SUPERBLOCK_V2_BYTES))
        if len(head) < SUPERBLOCK_V2_BYTES or head[8] not in (2, 3) or head[9] != 8:
            return  # other superblocks have no such flags
        head[11] = 0
        head[44:48] = lookup3(bytes(head[:44])).to_bytes(4, "little")
        handle.seek(0)
        handle.write(head)


@dataclass(frozen=True)
class RepairReport:
    """What ``repair_recording`` kept and lost."""

    source: Path
    destination: Path
    kept: dict[str, int]  # samples (edges for pulse channels) kept per channel
    lost: dict[str, int]  # samples (edges) that could not be read, per channel
    findings: tuple[str, ...]  # what was wrong with the file, in words

    def summary(self) -> str:
        """Several lines for the user."""
        lines = [f"{self.destination}: repaired copy of {self.source}"]
        lines += [f"  {finding}" for finding in self.findings]
        for name, kept in self.kept.items():
            lines.append(f"  {name}: {kept} kept, {self.lost.get(name, 0)} lost")
        return "\n".join(lines)


def _readable(dataset: h5py.Dataset, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Every element of ``dataset`` read ``step`` at a time; a failed piece reads as missing.
    Returns (data, good) where ``good`` marks the elements that were read."""
    size = dataset.shape[0]
    data = np.zeros(size, dtype=dataset.dtype)
    good = np.zeros(size, dtype=bool)
    for start in range(0, size, step):
        stop = min(size, start + step)
        try:
            data[start:stop] = dataset[start:stop]
            good[start:stop] = True
        except (OSError, RuntimeError, ValueError):
            pass
    return data, good


def repair_recording(source: str | Path, destination: str | Path) -> RepairReport:
    """Copy what can still be read of a damaged, truncated or killed recording into a new,
    closed recording; what cannot be read becomes gaps.  ``destination`` must not exist.

    Works on a scratch copy (beside ``destination``): padded to the length its writer
    recorded, with the writer flags cleared (as ``h5clear -s`` would), opened without SWMR
    so that every damaged piece fails at once instead of being retried.
    """
    source, destination = Path(source), Path(destination)
    block = read_superblock(source)
    findings = []
    if block.size < block.stored_eof:
        findings.append(
            f"truncated: {block.size} of {block.stored_eof} bytes present; the rest is lost"
        )
    if block.flags & _WRITER_FLAGS:
        findings.append("not closed by its writer (killed, or still being written)")
    scratch = destination.with_name(destination.name + ".repairing")
    with source.open("rb") as original, scratch.open("xb") as copy:
        while chunk := original.read(1 << 22):
            copy.write(chunk)
        copy.truncate(max(block.size, block.stored_eof))
    try:
        clear_writer_flags(scratch)
        try:
            damaged = h5py.File(scratch, "r")
        except OSError as error:
            raise RecordingDamagedError(
                f"{source}: nothing can be recovered; HDF5 cannot open even a cleared copy "
                f"({_first_line(error)})"
            ) from None
        with damaged:
            return _salvage(damaged, source, destination, findings)
    finally:
        scratch.unlink(missing_ok=True)


def _salvage(
    damaged: h5py.File, source: Path, destination: Path, findings: list[str]
) -> RepairReport:
    try:
        attrs = read_attributes(damaged)
    except (OSError, RuntimeError) as error:
        raise RecordingDamagedError(
            f"{source}: its metadata (root attributes) cannot be read ({_first_line(error)})"
        ) from None
    if attrs.get("format") != FORMAT_NAME:
        raise RecordingFormatError(f"{source}: not an impact-rig recording")

    def decoded(key: str, default: Any) -> Any:
        try:
            return json.loads(attrs[key]) if key in attrs else default
        except (json.JSONDecodeError, TypeError):
            findings.append(f"attribute {key} unreadable; left empty")
            return default

    specs, samples, pulses, kept, lost = _salvaged_channels(damaged, findings)
    tables = _salvaged_tables(damaged, findings)
    reason = _stop_reason(damaged)
    from analysis.provenance import provenance

    extra = decoded("extra_json", {})
    extra["repaired_from"] = str(source)
    extra["repair_findings"] = findings
    extra["source_provenance"] = decoded("provenance_json", {})
    meta = RecordingMetadata(
        experiment=str(attrs.get("experiment", "")),
        notes=str(attrs.get("notes", "")),
        rig=decoded("rig_json", {}),
        calibrations=decoded("calibrations_json", {}),
        devices=decoded("devices_json", {}),
        config_toml=str(attrs.get("config_toml", "")),
        drive=decoded("drive_json", None),
        roles=decoded("roles_json", {}),
        extra=extra,
        start_time_utc=str(attrs.get("start_time_utc", "")),
        provenance=provenance(),
    )
    writer = RecordingWriter(
        destination, specs, meta, software_version=str(attrs.get("software_version", ""))
    )
    try:
        for name, (raw, values, flags, rows, gaps, *_counts) in samples.items():
            writer.append_channel(name, {"raw": [raw], "values": [values], "flags": [flags]},
                                  rows, gaps)
        for name, (edges, times, rows, gaps, *_counts) in pulses.items():
            writer.append_channel(name, {"edge_indices": [edges], "edge_times_s": [times]},
                                  rows, gaps)
        writer.append_drive([tuple(r) for r in tables["drive"]])
        writer.append_steps([tuple(r) for r in tables["sweep_steps"]])
        writer.append_outages([tuple(r) for r in tables["outages"]])
        writer.write_status(
            RecordingStatus(
                end_host_time_s=0.0,
                samples_written=sum(len(v[0]) for v in samples.values()),
                samples_lost=sum(lost.values()),
                flushes=1,
                closed=True,
                stop_reason=f"repaired by impact-rig repair (the run ended: {reason})",
            )
        )
        writer.flush()
    finally:
        writer.close()
    return RepairReport(source, destination, kept, lost, tuple(findings))


def _salvaged_channels(damaged: h5py.File, findings: list[str]) -> tuple[
    list[ChannelSpec], dict[str, tuple[Any, ...]], dict[str, tuple[Any, ...]],
    dict[str, int], dict[str, int],
]:
    """The readable sample and pulse channels: specs, their salvaged data, and per channel the
    samples kept and lost; what cannot be read is noted in ``findings``."""
    specs, samples, pulses = [], {}, {}
    kept: dict[str, int] = {}
    lost: dict[str, int] = {}
    for top, kind in (("channels", "samples"), ("pulses", "pulses")):
        try:
            names = list(damaged[top].keys())
        except (OSError, RuntimeError, KeyError):
            findings.append(f"/{top} unreadable: its channels are lost")
            continue
        for name in names:
            try:
                group = damaged[top][name]
                group_attrs = read_attributes(group)
                rate = float(group_attrs["sample_rate_hz"])
                spec = ChannelSpec(
                    name,
                    kind,
                    str(group_attrs.get("unit", "")),
                    rate,
                    str(group_attrs.get("device", "")),
                    json.loads(group_attrs.get("calibration_json", "null")),
                    str(group["raw"].dtype) if kind == "samples" else "int32",
                )
                rows, rows_good = _readable(group["blocks"], TABLE_CHUNK_ROWS)
                gaps, gaps_good = _readable(group["gaps"], TABLE_CHUNK_ROWS)
            except (OSError, RuntimeError, KeyError, ValueError, TypeError) as error:
                findings.append(f"/{top}/{name} unreadable ({_first_line(error)}): lost")
                continue
            if not rows_good.all():
                findings.append(f"/{top}/{name}/blocks: {int((~rows_good).sum())} rows unreadable")
            specs.append(spec)
            if kind == "samples":
                samples[name] = _salvage_samples(group, rows[rows_good], gaps[gaps_good], rate)
                kept[name], lost[name] = samples[name][-2:]
            else:
                pulses[name] = _salvage_pulses(group, rows[rows_good], gaps[gaps_good])
                kept[name], lost[name] = pulses[name][-2:]
    return specs, samples, pulses, kept, lost


def _salvaged_tables(damaged: h5py.File, findings: list[str]) -> dict[str, np.ndarray]:
    """The readable rows of the drive, sweep-step and outage tables (empty where a table is
    lost, or absent from an older file)."""
    tables = {}
    for name, dtype in (("drive", DRIVE_DTYPE), ("sweep_steps", STEP_DTYPE),
                        ("outages", OUTAGE_DTYPE)):
        if name in OPTIONAL_ROOT_TABLES and name not in damaged:
            tables[name] = np.zeros(0, dtype)
            continue
        try:
            rows, good = _readable(damaged[name], TABLE_CHUNK_ROWS)
            tables[name] = rows[good]
            if not good.all():
                findings.append(f"/{name}: {int((~good).sum())} rows unreadable")
        except (OSError, RuntimeError, KeyError):
            tables[name] = np.zeros(0, dtype)
            findings.append(f"/{name} unreadable: lost")
    return tables


def _stop_reason(damaged: h5py.File) -> str:
    """Why the damaged run stopped, as its status row says (when that row can be read)."""
    try:
        status = damaged["status"][0]
        return bytes(status["stop_reason"]).rstrip(b"\0").decode("utf-8", "replace")
    except (OSError, RuntimeError, KeyError):
        return "unknown (status unreadable)"


def _salvage_samples(
    group: h5py.Group, rows: np.ndarray, gaps: np.ndarray, fs: float
) -> tuple[Any, ...]:
    """The readable samples of a channel, re-cut into blocks; unreadable stretches as gaps."""
    step = group["raw"].chunks[0] if group["raw"].chunks else 4096
    parts = [p for p in ("raw", "values", "flags") if p in group]
    read = {p: _readable(group[p], step) for p in parts}
    stored = min(read[p][0].size for p in parts)
    good = np.ones(stored, dtype=bool)
    for part in parts:
        good &= read[part][1][:stored]
    flags = read["flags"][0][:stored] if "flags" in read else np.zeros(stored, np.uint8)
    out_rows: list[tuple] = []
    out_gaps = [tuple(g) for g in gaps]
    keep = np.zeros(stored, dtype=bool)
    written = lost = 0
    for row in rows:
        start, n = int(row["stored_start"]), int(row["n_samples"])
        if n <= 0 or start < 0 or start + n > stored:
            continue  # its samples were never stored (the writer died first)
        mask = good[start : start + n]
        edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.view(np.int8), [0]))))
        for run_start, run_stop in zip(edges[0::2], edges[1::2], strict=True):
            out_rows.append(
                (
                    int(row["first_index"]) + int(run_start),
                    int(run_stop - run_start),
                    written,
                    float(row["timestamp_s"]) + run_start / fs,
                    float(row["host_time_s"]),
                    int(row["lost_before"]) if run_start == 0 else 0,
                )
            )
            written += int(run_stop - run_start)
        keep[start : start + n] = mask
        bad = np.flatnonzero(~mask)
        if bad.size:
            lost += int(bad.size)
            breaks = np.flatnonzero(np.diff(bad) != 1) + 1
            for piece in np.split(bad, breaks):
                out_gaps.append((int(row["first_index"]) + int(piece[0]), int(piece.size)))
    out_gaps.sort()
    return (
        read["raw"][0][:stored][keep],
        read["values"][0][:stored][keep],
        flags[keep],
        out_rows,
        out_gaps,
        written,
        lost,
    )


def _salvage_pulses(group: h5py.Group, rows: np.ndarray, gaps: np.ndarray) -> tuple[Any, ...]:
    """The pulse blocks whose edges can all be read; the others are dropped whole."""
    edges, edges_good = _readable(group["edge_indices"], 1024)
    times, times_good = _readable(group["edge_times_s"], 1024)
    stored = min(edges.size, times.size)
    good = edges_good[:stored] & times_good[:stored]
    kept_rows, kept_edges, kept_times = [], [], []
    position = lost = 0
    for row in rows:
        n = int(row["n_edges"])
        span = slice(position, position + n)
        position += n
        if position > stored:
            break
        if good[span].all():
            kept_rows.append(tuple(row))
            kept_edges.append(edges[span])
            kept_times.append(times[span])
        else:
            lost += n
    edge_array = np.concatenate(kept_edges) if kept_edges else np.zeros(0, np.int64)
    time_array = np.concatenate(kept_times) if kept_times else np.zeros(0)
    return edge_array, time_array, kept_rows, [tuple(g) for g in gaps], edge_array.size, lost
