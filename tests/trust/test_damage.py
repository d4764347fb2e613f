"""Damaged, truncated and killed files are found, never used: every command answers with one
line naming the file, exits non-zero within seconds, and shows no traceback."""

from __future__ import annotations

import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from recording.checksum import lookup3
from recording.reader import open_recording
from recording.superblock import clear_writer_flags
from tests.trust.conftest import REPO, run_cli

COMMANDS = {
    "export": lambda f, out: ["export", str(f), "--out", str(out / "x.csv"), "--gaps", "split"],
    "analyze": lambda f, out: ["analyze", str(f), "--workers", "1"],
    "identify": lambda f, out: ["identify", str(f)],
    "replay": lambda f, out: ["replay", str(f), "--fast"],
}
HANG_S = 60.0  # a hang bound per command (run_cli's subprocess timeout), not a speed figure:
# the fuzz benchmark (benchmarks/fuzz.py) carries how fast a damaged file is refused


def _stored_byte_ranges(path):
    """(start, stop, dataset) of every stored chunk of the file."""
    ranges = []
    with h5py.File(path, "r") as f:

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and obj.chunks:
                for k in range(obj.id.get_num_chunks()):
                    info = obj.id.get_chunk_info(k)
                    ranges.append((info.byte_offset, info.byte_offset + info.size, name))

        f.visititems(visit)
    return sorted(ranges)


def _zero_stored_bytes_near(path, fraction):
    """Zero 512 bytes of stored, non-zero data at the chunk nearest ``fraction`` of the file
    (zeroing bytes that were zero already, or free space, damages nothing)."""
    data = path.read_bytes()
    target = int(fraction * len(data))
    for start, stop, _ in sorted(_stored_byte_ranges(path), key=lambda r: abs(r[0] - target)):
        first = min(max(start, target), stop - 512) if stop - start >= 512 else start
        piece = data[first : first + 512]
        if any(piece):
            with path.open("r+b") as handle:
                handle.seek(first)
                handle.write(bytes(len(piece)))
            return first
    raise AssertionError("no stored data in the file")


def _damaged(kind, recording, killed_recording, folder):
    path = folder / f"{kind}.h5"
    if kind == "first_3000_bytes_of_killed":
        path.write_bytes(killed_recording.read_bytes()[:3000])
        return path
    shutil.copy(recording, path)
    if kind == "truncated_to_half":
        with path.open("r+b") as handle:
            handle.truncate(path.stat().st_size // 2)
    else:
        _zero_stored_bytes_near(path, {"zeros_at_quarter": 0.25, "zeros_at_half": 0.5,
                                       "zeros_at_three_quarters": 0.75}[kind])
    return path


KINDS = ["truncated_to_half", "zeros_at_quarter", "zeros_at_half", "zeros_at_three_quarters",
         "first_3000_bytes_of_killed"]


@pytest.mark.parametrize("kind", KINDS)
def test_every_command_refuses_a_damaged_file_in_one_line(
    kind, recording, killed_recording, tmp_path
):
    path = _damaged(kind, recording, killed_recording, tmp_path)
    for name, arguments in COMMANDS.items():
        done = run_cli(*arguments(path, tmp_path), timeout_s=HANG_S)
        lines = done.stderr.strip().splitlines()
        assert done.returncode != 0, f"{name} used the damaged {kind} file: {done.stdout[-300:]}"
        assert "Traceback" not in done.stderr, f"{name}: {done.stderr}"
        error_lines = [line for line in lines if "error:" in line]
        assert len(error_lines) == 1 and str(path) in error_lines[0], f"{name}: {lines}"
    assert not list(tmp_path.glob("x*.csv"))  # nothing was exported from it


def test_zeros_where_nothing_is_stored_change_no_result(recording, tmp_path):
    """Bytes outside every stored chunk or header are not data: the export is unchanged or
    refused, never different."""
    reference = run_cli("export", str(recording), "--out", str(tmp_path / "ref.csv"))
    assert reference.returncode == 0
    for fraction in (0.25, 0.5, 0.75):
        path = tmp_path / f"raw{fraction}.h5"
        shutil.copy(recording, path)
        with path.open("r+b") as handle:
            handle.seek(int(fraction * path.stat().st_size))
            handle.write(bytes(512))
        out = tmp_path / f"raw{fraction}.csv"
        done = run_cli("export", str(path), "--out", str(out))
        if done.returncode == 0:
            assert out.read_bytes() == (tmp_path / "ref.csv").read_bytes()
        else:
            assert "Traceback" not in done.stderr and str(path) in done.stderr


SWEEP_METADATA = """
import sys
from pathlib import Path
from analysis.hdf5_records import read_recording_arrays
from recording.errors import RecordFormatError
source, folder = Path(sys.argv[1]), Path(sys.argv[2])
whole = source.read_bytes()
reference = read_recording_arrays(source)
refused = same = 0
for offset in map(int, sys.argv[3:]):
    path = folder / f"at{offset}.h5"
    path.write_bytes(whole[:offset] + bytes(512) + whole[offset + 512:])
    try:
        arrays = read_recording_arrays(path)
    except RecordFormatError as error:
        assert str(error).startswith(f"{path}: ") and len(str(error).splitlines()) == 1, error
        refused += 1
    else:
        assert (arrays.angle_rad == reference.angle_rad).all(), offset
        assert (arrays.tach_edges == reference.tach_edges).all(), offset
        same += 1
    path.unlink()
print(refused, same)
"""


def test_zeros_anywhere_in_the_metadata_are_refused_in_one_line_or_change_nothing(
    recording, tmp_path
):
    """Every 512-byte window outside the stored chunks of the file's first 32 KiB (object
    headers, attribute storage, B-trees): HDF5 once looped forever on a zeroed global heap."""
    chunks = _stored_byte_ranges(recording)
    offsets = [
        offset for offset in range(0, min(32_768, recording.stat().st_size - 512), 512)
        if not any(start < offset + 512 and offset < stop for start, stop, _ in chunks)
    ]
    done = subprocess.run(
        [sys.executable, "-c", SWEEP_METADATA, str(recording), str(tmp_path), *map(str, offsets)],
        cwd=REPO, capture_output=True, text=True, timeout=60, check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    refused, same = map(int, done.stdout.split())
    assert refused >= len(offsets) // 2, (refused, same)  # most of it is live metadata


def test_a_killed_recording_with_damaged_metadata_is_refused_within_seconds(
    killed_recording, tmp_path
):
    """A killed file is read for SWMR, whose checksum retries once waited for days."""
    path = tmp_path / "killed.h5"
    data = bytearray(killed_recording.read_bytes())
    heap = data.find(b"FHDB")  # the root attributes' heap block (dense attribute storage)
    assert heap > 0
    data[heap : heap + 512] = bytes(512)
    path.write_bytes(bytes(data))
    # the retries waited for days: run_cli's timeout fails the test (TimeoutExpired) on a hang
    done = run_cli("export", str(path), "--out", str(tmp_path / "x.csv"), timeout_s=HANG_S)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert f"{path}: / is damaged" in done.stderr


def test_text_attributes_are_fixed_length_strings(recording):
    """No variable-length strings: they would live in the global heap, which has no checksum."""
    with h5py.File(recording, "r") as f:
        nodes = [f]
        f.visititems(lambda name, node: nodes.append(node))
        for node in nodes:
            for key in node.attrs:
                info = h5py.check_string_dtype(node.attrs.get_id(key).dtype)
                assert info is None or info.length is not None, f"{node.name} {key}"
    assert b"GCOL" not in recording.read_bytes()


def test_the_superblock_checksum_is_hdf5s_lookup3(recording):
    head = recording.read_bytes()[:48]
    assert lookup3(head[:44]) == int.from_bytes(head[44:48], "little")


def test_repair_recovers_a_killed_file_and_h5py_without_swmr_opens_the_copy(
    killed_recording, tmp_path
):
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(killed_recording, "r")  # what other tools meet: the reason repair exists
    out = tmp_path / "repaired.h5"
    done = run_cli("repair", str(killed_recording), "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "not closed by its writer" in done.stdout
    with open_recording(killed_recording) as original, open_recording(out) as repaired:
        np.testing.assert_array_equal(repaired.channel("angle").raw, original.channel("angle").raw)
        assert repaired.status().closed
    with h5py.File(out, "r") as plain:  # no SWMR needed any more
        assert plain["channels/angle/time_s"].shape[0] >= 4_000


def test_repair_of_damaged_bytes_keeps_the_rest_and_names_the_loss(recording, tmp_path):
    path = tmp_path / "damaged.h5"
    shutil.copy(recording, path)
    ranges = [r for r in _stored_byte_ranges(path) if r[2] == "channels/angle/values"]
    start, stop, _ = max(ranges, key=lambda r: r[1] - r[0])
    with path.open("r+b") as handle:
        handle.seek((start + stop) // 2)
        handle.write(bytes(64))
    done = run_cli("export", str(path), "--out", str(tmp_path / "d.csv"))
    assert done.returncode != 0 and "channels/angle/values is damaged" in done.stderr
    out = tmp_path / "fixed.h5"
    assert run_cli("repair", str(path), "--out", str(out)).returncode == 0
    with open_recording(recording) as whole, open_recording(out) as fixed:
        kept = fixed.channel("angle")
        total = len(whole.channel("angle"))
        assert 0 < len(kept) < total
        assert int(kept.gaps["length"].sum()) == total - len(kept)  # lost stretch = a gap
        np.testing.assert_array_equal(
            kept.raw, whole.channel("angle").raw[np.isin(whole.channel("angle").indices,
                                                         kept.indices)]
        )


def test_clearing_the_writer_flags_keeps_a_valid_superblock(killed_recording, tmp_path):
    path = tmp_path / "cleared.h5"
    shutil.copy(killed_recording, path)
    clear_writer_flags(path)
    with h5py.File(path, "r") as plain:
        assert "channels" in plain


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.attrs.__setitem__("format_version", 99), "format_version is 99"),
        (lambda f: f.attrs.__setitem__("format", "other"), "not an impact-rig recording"),
        (lambda f: _set_block_time(f, 3, np.nan), "row 3: timestamp_s is not a finite"),
        (lambda f: _set_block_time(f, 5, -1.0), "row 5: timestamp_s does not increase"),
        (lambda f: f.__delitem__("channels/angle/time_s"), "no /channels/angle/time_s"),
    ],
)
def test_values_at_the_boundary_are_refused_with_the_row_named(recording, tmp_path, change,
                                                                message):
    path = tmp_path / "edited.h5"
    shutil.copy(recording, path)
    with h5py.File(path, "r+") as f:
        change(f)
    with pytest.raises(ValueError, match=message), open_recording(path) as rec:
        rec.channel("angle")


def _set_block_time(f, row, value):
    blocks = f["channels/angle/blocks"]
    rows = blocks[()]
    rows["timestamp_s"][row] = value
    blocks[...] = rows
