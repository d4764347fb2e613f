"""Generated input at every boundary that reads bytes from outside: the DAQ frame decoder,
the exchange CSV and its sidecar, the rig file, a recording with damaged bytes.

Each answer is a correct result or one line naming what was wrong (harness.fuzz.boundaries
says how each is judged).  Bounded and deterministic: derandomized Hypothesis, a fixed
number of examples, no example database; ``benchmarks/fuzz.py`` runs the same checks for
as long as asked.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from harness.fuzz.boundaries import (
    DAMAGES,
    check_damaged_recording,
    check_exchange,
    check_frames,
    check_rig_file,
    exchange_files,
    frame_streams,
    read_everything,
    rig_files,
    write_small_recording,
)
from recording.errors import RecordingFormatError
from recording.superblock import HDF5_SIGNATURE, read_superblock


def bounded(examples: int) -> settings:
    """Deterministic settings with a fixed number of examples."""
    return settings(
        max_examples=examples,
        derandomize=True,
        database=None,
        deadline=None,  # timed by the checks themselves (5 s per answer), not per example
        suppress_health_check=[
            HealthCheck.too_slow,
            HealthCheck.data_too_large,
            HealthCheck.function_scoped_fixture,  # the recording is only read
        ],
    )


@bounded(300)
@given(frame_streams())
def test_the_frame_decoder_never_invents_a_sample_and_never_raises(stream):
    check_frames(*stream)


@bounded(200)
@given(exchange_files())
def test_an_exchange_file_is_read_correctly_or_refused_in_one_line(files):
    with tempfile.TemporaryDirectory() as folder:
        check_exchange(*files, Path(folder))


@bounded(200)
@given(rig_files())
def test_a_damaged_rig_file_is_loaded_or_refused_in_one_line(text):
    check_rig_file(text)


@pytest.fixture(scope="module")
def small_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("recording") / "small.h5"
    write_small_recording(path)
    return path


@bounded(60)
@given(damage=DAMAGES)
def test_a_damaged_recording_reads_as_written_or_is_refused_in_one_line(small_recording, damage):
    with tempfile.TemporaryDirectory() as folder:
        check_damaged_recording(small_recording, damage, Path(folder))


@pytest.mark.parametrize("version", [0, 1, 2, 3, 4])
def test_a_superblock_whose_version_byte_is_damaged_is_refused_in_one_line(tmp_path, version):
    # found by benchmarks/fuzz.py: a version byte turned to 1 made the reader unpack the
    # end-of-file address at bytes 44-52 of the 48 it had read (struct.error, a traceback)
    for size in (9, 40, 48):
        head = bytearray(HDF5_SIGNATURE + bytes(size - len(HDF5_SIGNATURE)))
        head[8] = version
        damaged = tmp_path / f"v{version}_{size}.h5"
        damaged.write_bytes(bytes(head))
        needed = {0: 48, 1: 52, 2: 48, 3: 48}.get(version)  # the HDF5 format's sizes
        if needed is not None and size >= needed:
            assert read_superblock(damaged).version == version
            continue
        with pytest.raises(RecordingFormatError) as refused:
            read_superblock(damaged)
        assert "\n" not in str(refused.value) and str(damaged) in str(refused.value)


@pytest.mark.parametrize("size_byte", [9, 10])
def test_a_live_recording_whose_superblock_sizes_are_damaged_is_refused_in_one_line(
    small_recording, tmp_path, size_byte
):
    # found by benchmarks/fuzz.py: with the writer flags set, HDF5's SWMR open raised
    # RuntimeError ("Can't decode file superblock prefix"), which escaped as a traceback
    data = bytearray(small_recording.read_bytes())
    data[11] = 0x05  # the writer's flags: opened for SWMR reading
    data[size_byte] = 0  # the size of offsets (9) or of lengths (10)
    damaged = tmp_path / "live.h5"
    damaged.write_bytes(bytes(data))
    with pytest.raises(RecordingFormatError) as refused:
        read_everything(damaged)
    assert "\n" not in str(refused.value) and str(damaged) in str(
        refused.value
    )
