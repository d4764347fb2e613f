"""The board as the wire sees it: raw bytes on its pty, no driver in between.

Run against both boards on a pty: the Python emulator and the C firmware core's host
build.  Replies are compared byte for byte with frames built from docs/daq_protocol.md
(the reference reply frame of section 5 among them); streams are decoded with the
driver's frame parser and checked sample by sample against the counter source.
"""

from __future__ import annotations

import os
import select
import time
import tty

import numpy as np
import pytest

from drivers.daq_protocol import FrameParser
from hardware_sim.daq_faults import OVERFLOW
from hardware_sim.sample_source import (
    CounterSource,
    expected_angle_counts,
    expected_table_counts,
)
from tests.daq.test_protocol import REFERENCE_REPLY_FRAME, bitwise_crc32


def reply_frame(text: str) -> bytes:
    """A reply frame assembled field by field from the document, with the bitwise CRC."""
    payload = text.encode("ascii")
    body = bytes([0x02, 0x00]) + len(payload).to_bytes(2, "little") + bytes(4) + payload
    return b"\xa5\x5a\xc3\x3c" + body + bitwise_crc32(body).to_bytes(4, "little")


def open_raw(port: str) -> int:
    fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    return fd


@pytest.fixture
def wire(make_pty_board):
    board = make_pty_board(CounterSource(), speed=1.0)
    fd = open_raw(board.port)
    yield board, fd
    os.close(fd)


def exchange(fd: int, line: bytes, n_bytes: int) -> bytes:
    os.write(fd, line)
    received = b""
    deadline = time.monotonic() + 2
    while len(received) < n_bytes and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.1)[0]:
            received += os.read(fd, n_bytes - len(received))
    return received


def test_start_is_answered_with_the_reference_reply_frame(wire):
    _, fd = wire
    expected = reply_frame("OK rate_hz=20000.0 channels=0 samples_per_frame=200")
    assert exchange(fd, b"CONF 20000 0\n", len(expected)) == expected
    got = exchange(fd, b"START\n", len(REFERENCE_REPLY_FRAME))
    assert got.hex(" ") == REFERENCE_REPLY_FRAME.hex(" ")
    # First data frame: input 0 only, 200 samples of (int16 + digital word), index 0.
    header = exchange(fd, b"", 12)
    assert header.hex(" ") == "a5 5a c3 3c 01 01 20 03 00 00 00 00"


def test_unknown_and_malformed_commands_get_error_replies(wire):
    _, fd = wire
    for line, text in [
        (b"FOO\n", "ERR unknown command 'FOO'"),
        (b"CONF 20000\n", "ERR CONF takes a rate in Hz and a channel list, e.g. CONF 20000 0,1"),
        (b"CONF 5 0\n", "ERR rate 5 Hz out of range 10..250000"),
        (b"CONF 1000 0,7\n", "ERR analog channel 7 does not exist (0..3)"),
        (b"CONF 1000 1,0\n", "ERR channel list 1,0 must be in ascending order"),
        (b"CONF fast 0\n", "ERR rate 'fast' is not a number"),
        (b"x" * 200, "ERR command line too long"),
    ]:
        expected = reply_frame(text)
        assert exchange(fd, line, len(expected)) == expected, line


def test_identity_reply_carries_the_documented_fields(wire, pty_board_kind):
    _, fd = wire
    serial = "HOST0001" if pty_board_kind == "firmware" else "SIM0001"
    text = (
        f"OK model=IRDAQ-4 serial={serial} firmware=1.0.0 channels=4 min_rate_hz=10 "
        "max_rate_hz=250000 adc_bits=16 range_v=10"
    )
    expected = reply_frame(text)
    assert exchange(fd, b"IDN?\r\n", len(expected)) == expected


def test_rates_and_channel_lists_are_answered_as_documented(wire):
    _, fd = wire
    odd_rate = "OK rate_hz=30030.03003003003 channels=0,1,3 samples_per_frame=256"
    for line, text in [
        (b"CONF 30000 0,1,3\n", odd_rate),
        (b"conf? \n", odd_rate),
        (b"CONF 10 2\n", "OK rate_hz=10.0 channels=2 samples_per_frame=1"),
        (b"CONF 250000 0,1,2,3\n", "OK rate_hz=250000.0 channels=0,1,2,3 samples_per_frame=256"),
        (b"CONF 7777.7 1\n", "OK rate_hz=7776.049766718507 channels=1 samples_per_frame=77"),
        (b"CONF 1e6 0\n", "ERR rate 1e+06 Hz out of range 10..250000"),
        (b"CONF nan 0\n", "ERR rate nan Hz out of range 10..250000"),
        (b"CONF 1000 0,,1\n", "ERR channel list '0,,1' is not comma-separated integers"),
        (b"CONF 1000 2,2\n", "ERR channel list '2,2' names a channel twice"),
        (b"CONF 1000 -1\n", "ERR analog channel -1 does not exist (0..3)"),
        (b"STOP\n", "OK streaming=0 samples=0"),
        (b"\n", "ERR empty command"),
        (b"START now\n", "ERR unknown command 'START now'"),
    ]:
        expected = reply_frame(text)
        assert exchange(fd, line, len(expected)) == expected, line


def read_frames(fd: int, parser: FrameParser, until, timeout_s: float = 10.0):
    """Decode what the board sends until ``until(runs, replies)`` holds."""
    runs, replies = [], []
    deadline = time.monotonic() + timeout_s
    while not until(runs, replies):
        assert time.monotonic() < deadline, f"the board never sent what was awaited: {replies}"
        if select.select([fd], [], [], 0.1)[0]:
            result = parser.feed(os.read(fd, 1 << 16))
            assert result.frames_rejected == 0 and result.bytes_discarded == 0
            runs += result.runs
            replies += result.replies
    return runs, replies


def assert_counter_stream(runs, lost_by_board: int, stop_reply: str) -> None:
    """Frames in index order from 0, every sample the counter's, every gap the board's own
    loss, and the STOP reply's count the end of the last frame (plus any skipped after it)."""
    expected_first = 0
    lost = 0
    for run in runs:
        assert run.first_index_wire >= expected_first  # never repeated or reordered
        lost += run.first_index_wire - expected_first
        index = np.arange(run.first_index_wire, run.first_index_wire + run.n_samples)
        assert np.array_equal(run.analog[:, 0], expected_angle_counts(index))
        assert np.array_equal(run.analog[:, 1], expected_table_counts(index))
        assert np.array_equal(run.digital, CounterSource().expected_tach(index))
        expected_first = run.first_index_wire + run.n_samples
    counted = int(stop_reply.rsplit("samples=", 1)[1])
    assert lost_by_board == lost + (counted - expected_first)


def test_a_command_mid_stream_is_answered_between_frames_and_costs_no_sample(wire):
    board, fd = wire
    parser = FrameParser()
    os.write(fd, b"CONF 20000 0,1\nSTART\n")
    runs, replies = read_frames(fd, parser, lambda runs, _: sum(r.n_samples for r in runs) > 4000)
    configured = "OK rate_hz=20000.0 channels=0,1 samples_per_frame=200"
    assert replies[:2] == [configured, "OK streaming=1"]
    os.write(fd, b"IDN?\nCONF?\nCONF 1000 0\nSTART\n")
    more, answers = read_frames(fd, parser, lambda _, replies: len(replies) == 4)
    assert answers[0].startswith("OK model=IRDAQ-4 ")
    assert answers[1:] == [
        configured,
        "ERR busy: STOP before CONF",
        "ERR already streaming",
    ]
    runs += more
    more, _ = read_frames(fd, parser, lambda more, _: sum(r.n_samples for r in more) > 2000)
    runs += more
    os.write(fd, b"STOP\n")
    more, stopped = read_frames(fd, parser, lambda _, replies: len(replies) == 1)
    runs += more
    assert_counter_stream(runs, board.faults.samples_lost(), stopped[0])
    assert runs[0].first_index_wire == 0


def test_a_host_that_stops_reading_overflows_the_board_which_skips_whole_frames(
    make_pty_board,
):
    board = make_pty_board(CounterSource(), speed=5.0, fifo_bytes=32 * 1024)
    fd = open_raw(board.port)
    try:
        parser = FrameParser()
        os.write(fd, b"CONF 20000 0,1\nSTART\n")
        runs, _ = read_frames(fd, parser, lambda runs, _: bool(runs))
        deadline = time.monotonic() + 15
        while not any(r.kind == OVERFLOW for r in board.faults.log):  # the host looks away
            assert time.monotonic() < deadline, "the board's FIFO never overflowed"
            time.sleep(0.05)
        more, _ = read_frames(fd, parser, lambda more, _: sum(r.n_samples for r in more) > 60_000)
        runs += more
        os.write(fd, b"STOP\n")
        more, stopped = read_frames(fd, parser, lambda _, replies: len(replies) == 1)
        runs += more
        overflow = [r for r in board.faults.log if r.kind == OVERFLOW]
        assert overflow and all(r.n_samples % 200 == 0 for r in overflow)  # whole frames
        assert_counter_stream(runs, board.faults.samples_lost(), stopped[0])
    finally:
        os.close(fd)
