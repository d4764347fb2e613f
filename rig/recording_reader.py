"""Read a recording (docs/recording_layout.md), also while it is being written or after a crash.

Everything returned is the file's consistent prefix: block rows whose samples are all
present, edges inside complete pulse blocks.  Files are opened read-only in SWMR mode.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from rig.recorder import FORMAT_NAME, FORMAT_VERSION


class RecordingFormatError(ValueError):
    """The file is not a readable impact-rig recording; the message names the file and the part."""


@dataclass(frozen=True)
class RecordingInfo:
    """The recording's metadata (root attributes), decoded."""

    experiment: str
    notes: str
    start_time_utc: str
    software_version: str
    format_version: int
    rig: dict[str, Any] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    devices: dict[str, Any] = field(default_factory=dict)
    config_toml: str = ""
    drive: dict[str, float] | None = None
    roles: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)


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


class Recording:
    """An open recording; call ``refresh()`` to see what a live writer flushed since."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._file = h5py.File(self.path, "r", libver="latest", swmr=True)
        except FileNotFoundError:
            raise RecordingFormatError(f"{self.path}: file not found") from None
        except OSError as error:
            raise RecordingFormatError(f"{self.path}: not a readable HDF5 file ({error})") from None
        attrs = self._file.attrs
        if attrs.get("format") != FORMAT_NAME:
            self._file.close()
            raise RecordingFormatError(
                f"{self.path}: attribute 'format' is {attrs.get('format')!r}; expected "
                f"{FORMAT_NAME!r} (not an impact-rig recording)"
            )
        if int(attrs.get("format_version", -1)) > FORMAT_VERSION:
            self._file.close()
            raise RecordingFormatError(
                f"{self.path}: format_version {attrs.get('format_version')} is newer than this "
                f"software reads ({FORMAT_VERSION}); update impact-rig"
            )
        self.info = RecordingInfo(
            experiment=str(attrs.get("experiment", "")),
            notes=str(attrs.get("notes", "")),
            start_time_utc=str(attrs.get("start_time_utc", "")),
            software_version=str(attrs.get("software_version", "")),
            format_version=int(attrs["format_version"]),
            rig=self._json("rig_json", {}),
            calibrations=self._json("calibrations_json", {}),
            devices=self._json("devices_json", {}),
            config_toml=str(attrs.get("config_toml", "")),
            drive=self._json("drive_json", None),
            roles=self._json("roles_json", {}),
            extra=self._json("extra_json", {}),
        )

    def _json(self, key: str, default: Any) -> Any:
        text = self._file.attrs.get(key)
        if text is None:
            return default
        try:
            return json.loads(text)
        except json.JSONDecodeError as error:
            raise RecordingFormatError(
                f"{self.path}: attribute {key!r} is not JSON ({error})"
            ) from None

    # -- structure ----------------------------------------------------------------------------

    @property
    def channel_names(self) -> list[str]:
        """Sampled channels (angle, table, ...)."""
        return list(self._file["channels"].keys())

    @property
    def pulse_names(self) -> list[str]:
        """Pulse channels (the tachometer)."""
        return list(self._file["pulses"].keys())

    def refresh(self) -> None:
        """See data a live writer flushed since the file was opened (SWMR)."""
        for obj in self._datasets():
            obj.refresh()

    def _datasets(self) -> Iterator[h5py.Dataset]:
        for top in ("channels", "pulses"):
            for group in self._file[top].values():
                yield from (d for d in group.values() if isinstance(d, h5py.Dataset))
        for name in ("drive", "sweep_steps", "status"):
            yield self._file[name]

    def _group(self, top: str, name: str) -> h5py.Group:
        try:
            return self._file[top][name]
        except KeyError:
            names = list(self._file[top].keys())
            raise RecordingFormatError(
                f"{self.path}: no {top[:-1]} named {name!r}; the file has {names}"
            ) from None

    # -- data ---------------------------------------------------------------------------------

    def _top(self, name: str) -> str:
        """'channels' or 'pulses', whichever holds ``name`` (an error naming all otherwise)."""
        if name in self.channel_names:
            return "channels"
        if name in self.pulse_names:
            return "pulses"
        raise RecordingFormatError(
            f"{self.path}: no channel {name!r}; the file has "
            f"{self.channel_names + self.pulse_names}"
        )

    def sample_rate_hz(self, name: str) -> float:
        """The nominal sample rate of a sampled or pulse channel."""
        return float(self._group(self._top(name), name).attrs["sample_rate_hz"])

    def unit(self, name: str) -> str:
        """The SI unit of a channel's calibrated values ('' for pulse channels)."""
        return str(self._group(self._top(name), name).attrs["unit"])

    def channel_dtype(self, name: str) -> np.dtype:
        """The stored dtype of a sampled channel's raw counts."""
        return self._group("channels", name)["raw"].dtype

    def complete_blocks(self, name: str) -> np.ndarray:
        """Rows of a sampled channel's block table whose samples are fully stored."""
        group = self._group("channels", name)
        blocks = group["blocks"][()]
        stored = min(group[part].shape[0] for part in _SAMPLE_DATASETS if part in group)
        return blocks[blocks["stored_start"] + blocks["n_samples"] <= stored]

    def channel(self, name: str) -> ChannelData:
        """All stored samples of a sampled channel (the consistent prefix)."""
        group = self._group("channels", name)
        blocks = self.complete_blocks(name)
        n = int(blocks["stored_start"][-1] + blocks["n_samples"][-1]) if blocks.size else 0
        fs = float(group.attrs["sample_rate_hz"])
        offset_in_block = np.arange(n) - np.repeat(blocks["stored_start"], blocks["n_samples"])
        indices = np.repeat(blocks["first_index"], blocks["n_samples"]) + offset_in_block
        times = np.repeat(blocks["timestamp_s"], blocks["n_samples"]) + offset_in_block / fs
        last = int(indices[-1]) + 1 if n else None
        gaps = group["gaps"][()]
        if last is not None:
            gaps = gaps[gaps["start_index"] < last]
        return ChannelData(
            name=name,
            unit=str(group.attrs["unit"]),
            sample_rate_hz=fs,
            indices=indices.astype(np.int64),
            times_s=times,
            raw=group["raw"][:n],
            values=group["values"][:n],
            flags=_flags(group, 0, n),
            gaps=gaps,
        )

    def pulses(self, name: str) -> PulseData:
        """Edges of a pulse channel inside its fully stored blocks."""
        group = self._group("pulses", name)
        blocks = group["blocks"][()]
        stored = min(group["edge_indices"].shape[0], group["edge_times_s"].shape[0])
        blocks = blocks[np.cumsum(blocks["n_edges"]) <= stored]
        n = int(blocks["n_edges"].sum())
        return PulseData(
            name=name,
            edge_indices=group["edge_indices"][:n],
            edge_times_s=group["edge_times_s"][:n],
            covered=blocks,
            gaps=group["gaps"][()],
        )

    def drive_log(self) -> np.ndarray:
        """Drive settings over time (structured: host_time_s, sample_index, frequency_hz, ...)."""
        return self._file["drive"][()]

    def sweep_steps(self) -> np.ndarray:
        """Sweep step marks (structured: step, direction, frequency_hz, amplitude_m, ...)."""
        return self._file["sweep_steps"][()]

    def status(self) -> RecordingStatus:
        """The writer's running totals as of its last flush."""
        row = self._file["status"][0]
        return RecordingStatus(
            end_host_time_s=float(row["end_host_time_s"]),
            samples_written=int(row["samples_written"]),
            samples_lost=int(row["samples_lost"]),
            flushes=int(row["flushes"]),
            closed=bool(row["closed"]),
            stop_reason=bytes(row["stop_reason"]).rstrip(b"\0").decode("utf-8", "replace"),
        )

    def role(self, role: str) -> str | None:
        """The channel playing ``role`` ('angle', 'table', 'tach'), or None."""
        return self.info.roles.get(role)

    # -- block-wise access (replay) -----------------------------------------------------------

    def iter_sample_blocks(
        self, name: str, max_samples: int = 4096, slab_samples: int = 1 << 18
    ) -> Iterator[SampleBlock]:
        """The channel's stored blocks as the driver delivered them, large blocks split.

        The file is read in slabs of ``slab_samples`` so that small blocks cost no
        HDF5 call each.
        """
        group = self._group("channels", name)
        fs = float(group.attrs["sample_rate_hz"])
        slab_start, raw, values = 0, group["raw"][:0], group["values"][:0]
        flags = _flags(group, 0, 0)
        for row in self.complete_blocks(name):
            start, n = int(row["stored_start"]), int(row["n_samples"])
            if start + n > slab_start + raw.size:
                slab_start = start
                stop = start + max(n, slab_samples)
                raw, values = group["raw"][start:stop], group["values"][start:stop]
                flags = _flags(group, start, stop)
            base = start - slab_start
            for offset in range(0, n, max_samples):
                count = min(max_samples, n - offset)
                part = slice(base + offset, base + offset + count)
                yield SampleBlock(
                    channel=name,
                    first_index=int(row["first_index"]) + offset,
                    timestamp_s=float(row["timestamp_s"]) + offset / fs,
                    sample_rate_hz=fs,
                    raw=raw[part],
                    values=values[part].astype(float),
                    lost_before=int(row["lost_before"]) if offset == 0 else 0,
                    flags=flags[part],
                )

    def iter_pulse_blocks(self, name: str) -> Iterator[PulseBlock]:
        """The pulse channel's blocks as the driver delivered them."""
        data = self.pulses(name)
        position = 0
        for row in data.covered:
            n = int(row["n_edges"])
            yield PulseBlock(
                channel=name,
                first_index=int(row["first_index"]),
                end_index=int(row["end_index"]),
                edge_indices=data.edge_indices[position : position + n],
                edge_times_s=data.edge_times_s[position : position + n],
                lost_before=int(row["lost_before"]),
            )
            position += n

    def close(self) -> None:
        """Release the file."""
        self._file.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def open_recording(path: str | Path) -> Recording:
    """Open a recording read-only (SWMR), validating that it is one."""
    return Recording(path)


# the per-sample datasets of a sampled channel; files of format 1 have no flags
_SAMPLE_DATASETS = ("raw", "values", "flags")


def _flags(group: h5py.Group, start: int, stop: int) -> np.ndarray:
    """Status flags of stored samples [start, stop); zeros (good) in a format-1 file."""
    if "flags" in group:
        return group["flags"][start:stop]
    stop = min(stop, group["raw"].shape[0])
    return np.zeros(max(stop - start, 0), dtype=np.uint8)
