"""A DAQ board that goes away mid-recording and comes back: the recording goes on.

The board is the emulator on a real pseudo-terminal, reached by the real serial driver
through a path that survives the replug (a symlink, as udev's /dev/serial/by-id links
do); the recording is a real HDF5 file.  The counter source makes every sample tell the
board's own index, so the file can be checked sample by sample: nothing invented,
nothing stored twice, and the outage recorded as a gap with its length.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from drivers.daq import DaqBoard
from drivers.interfaces import DeviceError
from drivers.sensors import (
    LaserCalibration,
    LaserDisplacementSensor,
    PotentiometerAngleSensor,
    PotentiometerCalibration,
    Tachometer,
)
from drivers.serial_daq import SerialDaqBackend
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.sample_source import CounterSource, expected_angle_counts
from recording.reader import open_recording
from rig.engine import AcquisitionEngine
from rig.recorder import ChannelSpec, Recorder, RecordingMetadata, attach_recorder

RATE_HZ = 20_000.0
SPEED = 1.0  # real time: the outage's length in samples is what the host clock saw


def wait_for(what: str, condition: Callable[[], bool], within_s: float = 20.0) -> None:
    """Wait on a state, bounded; the message says which state never came."""
    deadline = time.monotonic() + within_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {within_s} s")
        time.sleep(0.02)


def replug(port: Path, emulator: DaqEmulator) -> None:
    """Point the stable device path at a (new) board's pty."""
    port.unlink(missing_ok=True)
    port.symlink_to(emulator.port)


def make_board(port: Path, **options: object) -> DaqBoard:
    return DaqBoard(
        SerialDaqBackend(str(port)),
        sample_rate_hz=RATE_HZ,
        analog_channels=(0, 1),
        stall_timeout_s=0.3,
        reconnect_interval_s=0.05,
        **options,
    )


def test_a_recording_survives_the_board_going_away_and_coming_back(tmp_path):
    port = tmp_path / "ttyACM0"
    first = DaqEmulator(CounterSource(), speed=SPEED).start()
    replug(port, first)
    board = make_board(port, reconnect_for_s=30.0)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    table = LaserDisplacementSensor(board, 1, LaserCalibration())
    tach = Tachometer(board)
    engine = AcquisitionEngine([angle, table, tach])
    specs = [
        ChannelSpec("angle", "samples", "rad", RATE_HZ, "IRDAQ-4", None, "int16"),
        ChannelSpec("table", "samples", "m", RATE_HZ, "IRDAQ-4", None, "int16"),
        ChannelSpec("tach", "pulses", "", RATE_HZ, "IRDAQ-4", None),
    ]
    path = tmp_path / "replugged.h5"
    recorder = Recorder(path, specs, RecordingMetadata("forced"), flush_interval_s=0.25)
    writer = attach_recorder(engine, recorder)
    second: DaqEmulator | None = None
    try:
        board.start_roles(angle, table, tach)
        engine.start()
        wait_for("samples before the outage", lambda: (engine.aligned_end_index or 0) > 8_000)
        first.close()  # the cable is pulled: the pty goes away
        port.unlink()
        wait_for(
            "the engine saying every stream reconnects",
            lambda: set(engine.stats().reconnecting) == {"angle", "table", "tach"},
        )
        stats = engine.stats()
        assert "reconnecting" in stats.channels["angle"].message
        assert engine.running and engine.error is None
        before = engine.aligned_end_index or 0
        second = DaqEmulator(CounterSource(), speed=SPEED).start()
        replug(port, second)  # the same path appears again, on a new pty
        wait_for(
            "streaming after the replug", lambda: (engine.aligned_end_index or 0) > before + 8_000
        )
        stats = engine.stats()
        assert not stats.reconnecting and engine.error is None
        assert stats.channels["angle"].outages == 1
        assert "reconnected after" in stats.channels["angle"].message
    finally:
        engine.stop()
        writer.finish()
        recorder.close()
        board.close()
        first.close()
        if second is not None:
            second.close()
    assert writer.error is None

    with open_recording(path) as recording:
        outages = recording.outages()
        data = recording.channel("angle")
        table_data = recording.channel("table")
        tach_data = recording.pulses("tach")
        status = recording.status()
    assert status.closed and status.stop_reason == "completed"

    # the outage is in the file: one row per channel, the same stretch, its length given
    assert sorted(o.decode() for o in outages["channel"]) == ["angle", "table", "tach"]
    assert len(set(outages["start_index"])) == 1 and len(set(outages["length"])) == 1
    start, length = int(outages["start_index"][0]), int(outages["length"][0])
    outage_s = float(outages["outage_s"][0])
    assert outage_s > 0 and length == round(outage_s * RATE_HZ)
    # ... and is the gap of every channel (the gaps table and the jump in the block rows)
    for channel in (data, table_data, tach_data):
        assert [(int(g["start_index"]), int(g["length"])) for g in channel.gaps] == [
            (start, length)
        ]

    # every stored sample once: indices strictly increasing, one jump (the outage)
    indices = data.indices
    assert indices.size == data.raw.size == len(np.unique(indices))
    assert np.all(np.diff(indices) >= 1)
    jumps = np.flatnonzero(np.diff(indices) > 1)
    assert jumps.size == 1 and indices[jumps[0]] + 1 == start
    assert indices[jumps[0] + 1] == start + length
    # the first board's samples, then the second board's from its own index 0: each stored
    # once, none invented (the counter says which board sample each stored value is)
    before_gap, after_gap = indices < start, indices >= start + length
    assert np.array_equal(data.raw[before_gap], expected_angle_counts(indices[before_gap]))
    assert np.array_equal(
        data.raw[after_gap], expected_angle_counts(indices[after_gap] - (start + length))
    )
    assert indices[before_gap][0] == 0 and after_gap.sum() > 5_000
    # time goes on across the outage as the host saw it
    times = data.times_s
    assert times[jumps[0] + 1] - times[jumps[0]] == pytest.approx(
        (length + 1) / RATE_HZ, rel=1e-9
    )


def test_a_different_board_on_the_same_path_stops_the_stream(tmp_path):
    from dataclasses import replace

    from hardware_sim.daq_firmware import DEFAULT_IDENTITY

    port = tmp_path / "ttyACM0"
    first = DaqEmulator(CounterSource(), speed=SPEED).start()
    replug(port, first)
    board = make_board(port, reconnect_for_s=30.0)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    other = DaqEmulator(
        CounterSource(), speed=SPEED, identity=replace(DEFAULT_IDENTITY, serial="OTHER-2")
    )
    try:
        angle.start()
        wait_for("data", lambda: angle.read(0.1) is not None)
        first.close()
        port.unlink()
        wait_for("reconnecting", lambda: angle.status().reconnecting)
        replug(port, other.start())
        with pytest.raises(DeviceError, match="a different board answered"):
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                angle.read(0.1)
        assert not angle.status().running and not angle.status().reconnecting
    finally:
        angle.stop()
        board.close()
        first.close()
        other.close()


def test_a_board_that_never_comes_back_fails_the_stream_after_the_wait(tmp_path):
    port = tmp_path / "ttyACM0"
    first = DaqEmulator(CounterSource(), speed=SPEED).start()
    replug(port, first)
    board = make_board(port, reconnect_for_s=0.3)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    try:
        angle.start()
        wait_for("data", lambda: angle.read(0.1) is not None)
        first.close()
        port.unlink()
        with pytest.raises(DeviceError, match=r"no board answered within 0.3 s"):
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                angle.read(0.1)
    finally:
        angle.stop()
        board.close()
        first.close()
