"""What a recording holds (docs/recording_layout.md): the format's name and version, the dtypes
of its tables, the channels it records, and how each channel's datasets are chunked and packed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

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


# -- how channels are stored ---------------------------------------------------------------


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


def sample_times(rows: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """Device time of every sample of the block rows: timestamp_s + k / fs within a block."""
    counts = rows["n_samples"].astype(np.int64)
    offset = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(rows["timestamp_s"], counts) + offset / sample_rate_hz

