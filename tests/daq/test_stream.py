"""Streaming through the DAQ board and its role drivers, on both backends (pty serial, in-process).

The source is a counter: every sample says which index it is, so the tests check
sample by sample that nothing is invented, and that the lost-sample count equals
what the board's fault log says it damaged.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections import Counter

import numpy as np
import pytest

from drivers.daq import DaqBoard, RawChunk, RoleQueue
from drivers.interfaces import (
    DeviceError,
    InputStream,
    LimitError,
    PulseBlock,
    SampleBlock,
    StreamStatus,
    WrongDeviceError,
)
from drivers.sensors import (
    LaserCalibration,
    LaserDisplacementSensor,
    PotentiometerAngleSensor,
    PotentiometerCalibration,
    Tachometer,
)
from hardware_sim.daq_faults import CORRUPT_CRC, DROPPED_BYTES, GARBAGE, DaqFaults
from hardware_sim.daq_firmware import DEFAULT_IDENTITY
from hardware_sim.sample_source import (
    CounterSource,
    expected_angle_counts,
    expected_table_counts,
)

VOLTS_PER_COUNT = 10.0 / 32768  # the default board: 16-bit ADC over +-10 V


def read_until(role, end_index: int, timeout_s: float = 10.0) -> list:
    """Blocks from ``role`` until one reaches ``end_index`` (fails after ``timeout_s``)."""
    blocks: list = []
    deadline = time.monotonic() + timeout_s
    while not blocks or blocks[-1].end_index < end_index:
        assert time.monotonic() < deadline, f"stream did not reach index {end_index}"
        block = role.read(0.2)
        if block is not None:
            blocks.append(block)
    return blocks


def assert_never_invented(blocks: list[SampleBlock], expected) -> None:
    """Every delivered sample is the one the source produced at that index."""
    for block in blocks:
        index = np.arange(block.first_index, block.end_index)
        assert np.array_equal(block.raw, expected(index))


def assert_indices_account(blocks: list) -> None:
    """Consecutive blocks touch, once their reported gaps are counted: nothing unexplained."""
    for previous, block in itertools.pairwise(blocks):
        assert block.first_index - block.lost_before == previous.end_index


def test_three_roles_share_one_exact_stream(make_board):
    source = CounterSource(tach_period=333, tach_width=7, tach_phase=5)
    # Unpaced (the reader sets the pace, nothing overflows): a loaded machine cannot
    # turn a late reader into lost samples, so "no sample lost" is exact.
    board = make_board(source, speed=math.inf)
    angle_cal = PotentiometerCalibration(offset_v=0.25, gain_rad_per_v=0.3, linearity=(0.1, -0.05))
    laser_cal = LaserCalibration(zero_m=0.001, m_per_unit=0.005, measuring_range_m=(-0.05, 0.05))
    angle = PotentiometerAngleSensor(board, 0, angle_cal)
    laser = LaserDisplacementSensor(board, 1, laser_cal)
    tach = Tachometer(board)
    assert all(isinstance(role, InputStream) for role in (angle, laser, tach))
    board.start_roles(angle, laser, tach)
    end = 30_000
    angle_blocks = read_until(angle, end)
    laser_blocks = read_until(laser, end)
    tach_blocks = read_until(tach, end)
    for blocks in (angle_blocks, laser_blocks, tach_blocks):
        assert blocks[0].first_index == 0
        assert all(b.lost_before == 0 for b in blocks)
        assert_indices_account(blocks)

    assert_never_invented(angle_blocks, expected_angle_counts)
    assert_never_invented(laser_blocks, expected_table_counts)
    block = angle_blocks[-1]
    assert isinstance(block, SampleBlock) and block.channel == "angle"
    assert block.sample_rate_hz == 20_000.0
    assert block.timestamp_s == pytest.approx(block.first_index / 20_000.0)
    # Oracle: the calibration's formula written out with numpy's polynomial class.
    volts = block.raw.astype(float) * VOLTS_PER_COUNT
    a = 0.3 * (volts - 0.25)
    expected = np.polynomial.Polynomial([0.0, 1.0, 0.1, -0.05])(a)
    np.testing.assert_allclose(block.values, expected, rtol=1e-12, atol=1e-15)
    laser_block = laser_blocks[-1]
    np.testing.assert_allclose(
        laser_block.values, 0.001 + 0.005 * laser_block.raw * VOLTS_PER_COUNT, rtol=1e-12
    )

    assert all(isinstance(b, PulseBlock) for b in tach_blocks)
    edges = np.concatenate([b.edge_indices for b in tach_blocks])
    stop = tach_blocks[-1].end_index
    assert np.array_equal(edges, source.expected_rising_edges(0, stop))
    times = np.concatenate([b.edge_times_s for b in tach_blocks])
    np.testing.assert_allclose(times, edges / 20_000.0)

    status = angle.status()
    assert status.running and status.samples_lost == 0 and status.frames_rejected == 0
    assert status.samples_received == sum(len(b) for b in angle_blocks)


def test_tach_edges_on_frame_boundaries_are_found(make_board):
    # 20 kHz -> 200 samples per frame; every edge sits on the first sample of a frame,
    # so each is visible only through the level carried over from the previous block.
    source = CounterSource(tach_period=400, tach_width=200, tach_phase=0)
    board = make_board(source, speed=math.inf)  # lossless: every edge must be seen
    tach = Tachometer(board)
    tach.start()
    blocks = read_until(tach, 12_000)
    edges = np.concatenate([b.edge_indices for b in blocks])
    assert np.array_equal(edges, source.expected_rising_edges(0, blocks[-1].end_index))
    assert len(edges) >= 29


def test_as_fast_as_possible_stream_is_exact(make_board):
    board = make_board(CounterSource(), speed=math.inf)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    blocks = read_until(angle, 60_000)
    assert blocks[0].first_index == 0 and all(b.lost_before == 0 for b in blocks)
    assert_indices_account(blocks)
    assert_never_invented(blocks, expected_angle_counts)


FAULTS = {
    "corrupt_crc": (lambda f: f.corrupt_crc(frames=3), {CORRUPT_CRC: 3}),
    "dropped_bytes": (lambda f: f.drop_bytes(9, frames=2), {DROPPED_BYTES: 2}),
    "garbage": (lambda f: f.inject_garbage(333), {GARBAGE: 1}),
    "mixed_periodic": (
        lambda f: (f.corrupt_crc(every=7), f.inject_garbage(50, every=3), f.drop_bytes(3)),
        {CORRUPT_CRC: 4, GARBAGE: 8, DROPPED_BYTES: 1},
    ),
}


def read_past_faults(role, faults: DaqFaults, wanted: dict[str, int], blocks: list) -> list:
    """Read until the board has logged ``wanted`` faults, then until the role has read
    past all the damage and every gap the driver counted for it."""
    deadline = time.monotonic() + 15
    while True:
        blocks += read_until(role, blocks[-1].end_index + 1_000)
        logged = Counter(record.kind for record in faults.log)
        if all(logged[kind] >= n for kind, n in wanted.items()):
            break
        assert time.monotonic() < deadline, f"faults {wanted} never happened: {logged}"
    faults.clear()
    damage_end = max(r.first_index + r.n_samples for r in faults.log)
    while blocks[-1].end_index <= damage_end or (
        sum(b.lost_before for b in blocks) != role.status().samples_lost
    ):
        assert time.monotonic() < deadline, "the role's gaps never matched what it read"
        block = role.read(0.2)
        if block is not None:
            blocks.append(block)
    return blocks


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_faults_cost_exactly_the_samples_the_board_damaged(make_board, make_faults, fault):
    faults = make_faults(seed=7)
    board = make_board(CounterSource(), faults=faults)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    blocks = read_until(angle, 4_000)
    arm, wanted = FAULTS[fault]
    arm(faults)
    blocks = read_past_faults(angle, faults, wanted, blocks)
    end = blocks[-1].end_index

    assert_indices_account(blocks)
    assert_never_invented(blocks, expected_angle_counts)
    lost = sum(b.lost_before for b in blocks)
    assert lost == faults.samples_lost(before_index=end)  # the board's own log: exact
    damaged_frames = [r for r in faults.log if r.kind in (CORRUPT_CRC, DROPPED_BYTES)]
    if fault == "garbage":
        assert not damaged_frames
    else:
        assert lost >= sum(r.n_samples for r in damaged_frames) > 0
    received = sum(len(b) for b in blocks)
    assert received + lost == end
    assert angle.status().frames_rejected == len(damaged_frames)


def test_stalled_board_times_out_reports_and_recovers_with_exact_loss(make_board, make_faults):
    faults = make_faults()
    board = make_board(CounterSource(), faults=faults, speed=2.0)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    blocks = read_until(angle, 2_000)
    faults.stall()  # until resumed
    silent_reads = 0
    deadline = time.monotonic() + 5
    while "no data" not in angle.status().message:
        assert time.monotonic() < deadline, "a stalled board was never reported"
        block = angle.read(0.1)  # returns within its timeout: no hang
        if block is None:
            silent_reads += 1
        else:
            blocks.append(block)
    assert silent_reads >= 1
    assert "stalled" in angle.status().message
    faults.resume()
    # A board with a FIFO sends what it holds before the gap: read past the logged loss.
    damage_end = max((r.first_index + r.n_samples for r in faults.log), default=0)
    blocks += read_until(angle, max(blocks[-1].end_index, damage_end) + 4_000)
    end = blocks[-1].end_index
    lost = sum(b.lost_before for b in blocks)
    assert lost > 0 and lost == faults.samples_lost(before_index=end)
    assert_never_invented(blocks, expected_angle_counts)
    assert angle.status().message.startswith("lost ")  # the silence report is cleared


@pytest.mark.timeout(60)
def test_unplugged_board_fails_cleanly_with_a_clear_message(make_board, make_faults, backend_kind):
    faults = make_faults()
    board = make_board(CounterSource(), faults=faults)
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    read_until(angle, 1_000)
    faults.unplug()
    deadline = time.monotonic() + 5
    with pytest.raises(DeviceError, match="went away") as caught:
        while time.monotonic() < deadline:
            angle.read(0.1)
    where = "simulated IRDAQ-4" if backend_kind == "inprocess" else "serial port /dev/"
    assert where in str(caught.value)
    status = angle.status()
    assert isinstance(status, StreamStatus)
    assert not status.running and "went away" in status.message
    angle.stop()  # no hang on the way out: the test's timeout mark bounds it
    board.close()


def test_stop_then_start_begins_a_fresh_stream(make_board):
    board = make_board(CounterSource())
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    read_until(angle, 1_000)
    angle.stop()
    assert not angle.status().running
    angle.start()
    blocks = read_until(angle, 2_000)
    assert blocks[0].first_index == 0 and blocks[0].lost_before == 0
    assert_never_invented(blocks, expected_angle_counts)


def test_wrong_identity_is_refused(make_board):
    other = DEFAULT_IDENTITY.__class__(**{**DEFAULT_IDENTITY.__dict__, "model": "SCOPE-9"})
    board = make_board(CounterSource(), identity=other)
    with pytest.raises(WrongDeviceError, match=r"'SCOPE-9'.*expected a 'IRDAQ-4'"):
        board.open()


def test_rate_outside_the_board_limits_is_refused_before_the_wire(make_board):
    board = make_board(CounterSource(), sample_rate_hz=1e6)
    with pytest.raises(LimitError, match=r"sample_rate_hz=1e\+06 is outside the range 10..250000"):
        board.open()


def test_channel_the_board_lacks_is_refused(make_board):
    board = make_board(CounterSource(), analog_channels=(0, 6))
    with pytest.raises(LimitError, match=r"analog channel 6 does not exist.*channels 0\.\.3"):
        board.open()


def test_role_on_a_channel_not_enabled_is_refused(make_board):
    board = make_board(CounterSource(), analog_channels=(0,))
    with pytest.raises(LimitError, match=r"analog channel 2 is not enabled.*enabled: 0"):
        LaserDisplacementSensor(board, 2, LaserCalibration())


def test_board_reports_the_rate_its_clock_really_runs(make_board):
    board = make_board(CounterSource(), sample_rate_hz=30_000.0)
    board.open()
    assert board.sample_rate_hz == pytest.approx(1e7 / 333)  # 10 MHz / round(10 MHz / 30 kHz)


def test_board_declaration_validates_its_settings():
    with pytest.raises(LimitError, match="sample_rate_hz=-5"):
        DaqBoard(None, sample_rate_hz=-5, analog_channels=(0,))  # type: ignore[arg-type]
    with pytest.raises(LimitError, match="names a channel twice"):
        DaqBoard(None, sample_rate_hz=1000, analog_channels=(1, 1))  # type: ignore[arg-type]
    with pytest.raises(LimitError, match="analog_channels is empty"):
        DaqBoard(None, sample_rate_hz=1000, analog_channels=())  # type: ignore[arg-type]


def test_a_waiting_role_queue_holds_the_reader_back_and_never_drops():
    def chunk(first: int, n: int) -> RawChunk:
        return RawChunk(first, np.zeros((n, 1), dtype=np.int16), np.zeros(n, dtype=np.uint16))

    queue = RoleQueue(100, wait_when_full=True, stopping=threading.Event())
    queue.push(chunk(0, 60), 0)
    reader = threading.Thread(target=queue.push, args=(chunk(60, 60), 0))
    reader.start()
    reader.join(0.3)
    assert reader.is_alive()  # 60 + 60 would not fit in 100: the reader waits
    assert queue.queued_samples == 60 and queue.samples_lost == 0
    taken = queue.take(1.0, board=None)  # type: ignore[arg-type]
    assert taken is not None and taken[0].n_samples == 60
    reader.join(5.0)
    assert not reader.is_alive()
    taken = queue.take(1.0, board=None)  # type: ignore[arg-type]
    assert taken is not None and taken[0].first_index == 60 and taken[1] == 0
    assert queue.samples_lost == 0 and queue.samples_received == 120
