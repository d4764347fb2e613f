"""Repair: what can still be read of a damaged, truncated or killed recording, salvaged into a
new, cleanly closed one."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from recording.errors import RecordingDamagedError, RecordingFormatError, first_line
from recording.layout import (
    DRIVE_DTYPE,
    FORMAT_NAME,
    OPTIONAL_ROOT_TABLES,
    OUTAGE_DTYPE,
    STEP_DTYPE,
    TABLE_CHUNK_ROWS,
    ChannelSpec,
    RecordingStatus,
)
from recording.metadata import RecordingMetadata, metadata_fields, read_attributes
from recording.superblock import WRITER_FLAGS, clear_writer_flags, read_superblock
from recording.writer import RecordingWriter


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


def repair_recording(
    source: str | Path, destination: str | Path, *, provenance: Mapping[str, Any]
) -> RepairReport:
    """Copy what can still be read of a damaged, truncated or killed recording into a new,
    closed recording; what cannot be read becomes gaps.  ``destination`` must not exist;
    ``provenance`` says what made the copy (``analysis.provenance.provenance()``), the
    source's own is kept in its ``extra`` as ``source_provenance``.

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
    if block.flags & WRITER_FLAGS:
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
                f"({first_line(error)})"
            ) from None
        with damaged:
            return _salvage(damaged, source, destination, findings, provenance)
    finally:
        scratch.unlink(missing_ok=True)


def _salvage(
    damaged: h5py.File,
    source: Path,
    destination: Path,
    findings: list[str],
    provenance: Mapping[str, Any],
) -> RepairReport:
    try:
        attrs = read_attributes(damaged)
    except (OSError, RuntimeError) as error:
        raise RecordingDamagedError(
            f"{source}: its metadata (root attributes) cannot be read ({first_line(error)})"
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
    stored = metadata_fields(attrs, decoded)
    extra = {
        **stored["extra"],
        "repaired_from": str(source),
        "repair_findings": findings,
        "source_provenance": stored["provenance"],
    }
    meta = RecordingMetadata(**{**stored, "extra": extra, "provenance": dict(provenance)})
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
                findings.append(f"/{top}/{name} unreadable ({first_line(error)}): lost")
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
