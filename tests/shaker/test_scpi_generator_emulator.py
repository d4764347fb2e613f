"""The emulated generator at the byte level: what a raw socket sends, what it answers."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from hardware_sim.scpi_generator import MAX_LINE_BYTES, ScpiGeneratorEmulator


@pytest.fixture
def wire() -> Iterator[tuple[ScpiGeneratorEmulator, socket.socket]]:
    with ScpiGeneratorEmulator() as generator:
        assert generator.port is not None
        with socket.create_connection(("127.0.0.1", generator.port), timeout=2.0) as sock:
            yield generator, sock


def exchange(sock: socket.socket, request: bytes) -> bytes:
    """Send ``request`` and read one reply line."""
    sock.sendall(request)
    reply = b""
    while not reply.endswith(b"\n"):
        chunk = sock.recv(4096)
        assert chunk, "the emulator closed the connection"
        reply += chunk
    return reply


@pytest.mark.parametrize(
    ("request_bytes", "reply"),
    [
        (b"*IDN?\n", b"impact-rig,Emulated SCPI generator,SIM00001,1.0\n"),
        (b":SOURce1:FREQuency 12.5;:SOUR:FREQ?\n", b"+1.25000000000000E+01\n"),
        (b"FREQ 7;*OPC?\n", b"1\n"),
        (b"VOLT 2.5;VOLT?;VOLT:UNIT?\n", b"+2.50000000000000E+00;VPP\n"),
        (b"OUTP1 ON;OUTP1?\n", b"1\n"),
        (b"OUTPut OFF;OUTPut?\n", b"0\n"),
        (b"FUNC SINusoid;FUNC?\n", b"SIN\n"),
        (b"SYST:ERR?\n", b'+0,"No error"\n'),
        (b"BOGUS 1\nSYST:ERR?\n", b'-113,"Undefined header"\n'),
        (b"FREQ ten\nSYST:ERR?\n", b'-104,"Data type error"\n'),
        (b"SOUR2:FREQ 1\nSYST:ERR?\n", b'-114,"Header suffix out of range"\n'),
        (b"VOLT 100\nSYST:ERR?;VOLT?\n", b'-222,"Data out of range";+2.00000000000000E+01\n'),
    ],
)
def test_requests_and_replies_byte_for_byte(wire, request_bytes: bytes, reply: bytes) -> None:
    _, sock = wire
    assert exchange(sock, request_bytes) == reply


def test_a_line_too_long_is_dropped_with_an_error_and_the_link_goes_on(wire) -> None:
    generator, sock = wire
    sock.sendall(b"FREQ " + b"1" * (MAX_LINE_BYTES + 10) + b"\n")
    assert exchange(sock, b"SYST:ERR?\n") == b'-223,"Too much data"\n'
    assert generator.state.frequency_hz == 1000.0  # the power-on default: nothing was applied


def test_the_disconnect_watchdog_watches_only_the_connection_that_turned_the_output_on(
    wire,
) -> None:
    generator, sock = wire
    with socket.create_connection(("127.0.0.1", generator.port), timeout=2.0) as onlooker:
        assert exchange(onlooker, b"OUTP?\n") == b"0\n"
        assert exchange(sock, b"OUTP ON;*OPC?\n") == b"1\n"
    # the onlooker left: the output stays on
    assert generator.wait_for(lambda state: generator.connections == 1, 2.0)
    assert generator.state.output
    sock.close()  # the host that turned it on left
    assert generator.wait_for(lambda state: not state.output, 2.0)
    assert generator.watchdog_trips == 1
