"""The emulated board as the wire sees it: raw bytes on its pty, no driver in between.

Replies are compared byte for byte with frames built from docs/daq_protocol.md
(the reference reply frame of section 5 among them).
"""

from __future__ import annotations

import os
import select
import time
import tty

import pytest

from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.sample_source import CounterSource
from tests.daq.test_protocol import REFERENCE_REPLY_FRAME, bitwise_crc32


def reply_frame(text: str) -> bytes:
    """A reply frame assembled field by field from the document, with the bitwise CRC."""
    payload = text.encode("ascii")
    body = bytes([0x02, 0x00]) + len(payload).to_bytes(2, "little") + bytes(4) + payload
    return b"\xa5\x5a\xc3\x3c" + body + bitwise_crc32(body).to_bytes(4, "little")


@pytest.fixture
def wire():
    emulator = DaqEmulator(CounterSource(), speed=1.0).start()
    fd = os.open(emulator.port, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    yield emulator, fd
    os.close(fd)
    emulator.close()


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


def test_identity_reply_carries_the_documented_fields(wire):
    _, fd = wire
    text = (
        "OK model=IRDAQ-4 serial=SIM0001 firmware=1.0.0 channels=4 min_rate_hz=10 "
        "max_rate_hz=250000 adc_bits=16 range_v=10"
    )
    expected = reply_frame(text)
    assert exchange(fd, b"IDN?\r\n", len(expected)) == expected
