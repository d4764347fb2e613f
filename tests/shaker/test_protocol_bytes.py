"""Byte-level Modbus TCP exchanges with the emulator, beside docs/amplifier_registers.md."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from hardware_sim.amplifier_emulator import AmplifierEmulator


def _exchange(sock: socket.socket, request_hex: str) -> str:
    sock.sendall(bytes.fromhex(request_hex))
    header = _read_exactly(sock, 6)
    body = _read_exactly(sock, int.from_bytes(header[4:6], "big"))
    return (header + body).hex(" ").upper()


def _read_exactly(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("emulator closed the connection")
        data += chunk
    return data


@pytest.fixture
def link(emulator: AmplifierEmulator) -> Iterator[socket.socket]:
    with socket.create_connection(("127.0.0.1", emulator.port), timeout=2.0) as sock:
        yield sock


def test_documented_frames(link: socket.socket, emulator: AmplifierEmulator) -> None:
    # set the frequency to 10 Hz = 10 000 mHz = 0x0000 0x2710 (FC16, high word first)
    assert _exchange(link, "00 01 00 00 00 0B 01 10 00 00 00 02 04 00 00 27 10") == (
        "00 01 00 00 00 06 01 10 00 00 00 02"
    )
    assert emulator.firmware.read_holding(0, 2) == [0x0000, 0x2710]
    # identity block: model 0x5348, firmware 1.0, map version 1
    reply = _exchange(link, "00 02 00 00 00 06 01 04 00 00 00 09")
    assert reply.startswith("00 02 00 00 00 15 01 04 12 53 48 01 00 00 01")
    # FC6 single write: the reply echoes the request
    assert _exchange(link, "00 04 00 00 00 06 01 06 00 03 03 E8") == (
        "00 04 00 00 00 06 01 06 00 03 03 E8"
    )
    assert emulator.firmware.read_holding(3, 1) == [1000]
    # an amplitude beyond the device's own range: exception 0x03, nothing changed
    assert _exchange(link, "00 05 00 00 00 06 01 06 00 02 EA 60") == ("00 05 00 00 00 03 01 86 03")
    assert emulator.firmware.read_holding(2, 1) == [0]


def test_half_of_a_32_bit_value_is_refused(
    link: socket.socket, emulator: AmplifierEmulator
) -> None:
    assert _exchange(link, "00 07 00 00 00 06 01 06 00 01 13 88") == "00 07 00 00 00 03 01 86 03"
    assert emulator.firmware.read_holding(0, 2) == [0, 0]


def test_unknown_address_answers_illegal_address(link: socket.socket) -> None:
    assert _exchange(link, "00 08 00 00 00 06 01 04 00 09 00 01") == "00 08 00 00 00 03 01 84 02"
    assert _exchange(link, "00 09 00 00 00 06 01 03 00 07 00 02") == "00 09 00 00 00 03 01 83 02"


def test_measured_values_are_big_endian_scaled_integers(
    link: socket.socket, emulator: AmplifierEmulator
) -> None:
    emulator.firmware.response.settle_at(amplitude_m=0.001234, frequency_hz=70.5)
    reply = bytes.fromhex(_exchange(link, "00 0A 00 00 00 06 01 04 00 05 00 03"))
    assert reply[7:9] == b"\x04\x06"
    frequency_mhz = int.from_bytes(reply[9:13], "big")  # high word first
    amplitude_um = int.from_bytes(reply[13:15], "big")
    assert (frequency_mhz, amplitude_um) == (70_500, 1234)
