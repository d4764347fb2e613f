"""Reading a recording: opened in the right mode once it is known to be whole, validated, and
read as its consistent prefix."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from recording.errors import REPAIR_HINT, RecordingDamagedError, RecordingFormatError, first_line
from recording.hdf5_library import set_metadata_read_attempts
from recording.layout import (
    FORMAT_NAME,
    GAP_DTYPE,
    OPTIONAL_ROOT_TABLES,
    OUTAGE_DTYPE,
    PULSE_BLOCK_DTYPE,
    READABLE_VERSIONS,
    ROOT_TABLES,
    SAMPLE_BLOCK_DTYPE,
    ChannelData,
    PulseData,
    RecordingStatus,
    sample_times,
)
from recording.metadata import RecordingInfo, metadata_fields, read_attributes
from recording.superblock import WRITER_FLAGS, check_whole

# A SWMR reader's retries of a metadata block sleep 1 ns, 2 ns, 4 ns, ...: 30 attempts wait
# about a second in all (a live writer's flush takes milliseconds), 36 over a minute.
SWMR_METADATA_READ_ATTEMPTS = 30


def open_hdf5(path: str | Path) -> h5py.File:
    """A recording file opened read-only: SWMR while a writer has it (or died with it) open.

    A cleanly closed file is opened without SWMR, where a checksum failure is an error at
    once (SWMR readers retry each one for a long time, in case a writer is mid-flush).
    """
    path = Path(path)
    block = check_whole(path)
    live = bool(block.flags & WRITER_FLAGS)
    try:
        if live:
            return h5py.File(_open_swmr_reader(path))
        return h5py.File(path, "r")
    except (OSError, RuntimeError) as error:  # RuntimeError: a superblock HDF5 cannot decode
        raise RecordingDamagedError(
            f"{path}: HDF5 cannot open it ({first_line(error)}); " + REPAIR_HINT.format(path=path)
        ) from None


def _open_swmr_reader(path: Path) -> h5py.h5f.FileID:
    """``path`` opened read-only for SWMR, with metadata checksum failures retried for about
    a second at most (the library's default retries a damaged block for days)."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_LATEST)
    set_metadata_read_attempts(fapl, SWMR_METADATA_READ_ATTEMPTS)
    return h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl)


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
            **metadata_fields(attrs, lambda key, default: self._json(attrs, key, default)),
            software_version=str(attrs.get("software_version", "")),
            format_version=version,
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
            f"{self.path}: {where} is damaged ({first_line(error)}); "
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

