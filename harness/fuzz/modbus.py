"""The Modbus boundary under generated input, both ways, over loopback TCP.

The shaker driver against an amplifier that answers wrongly: the real pymodbus server
(the amplifier emulator) behind a proxy that mangles its replies as drawn: delayed past
the driver's timeout, dropped, the connection closed (or reset), truncated, another unit id or
transaction id, an exception code, a bit flipped, garbage around it, a wrong length
field, well-formed replies with random register values, with every word 0xFFFF, or with
fewer registers than asked.  :func:`check_driver` runs a
drawn sequence of the driver's operations: each returns, or raises ``DeviceError`` in one
line, within ``SLOW_S``; a reading it returns is one the amplifier can give (finite,
inside its own ranges: anything else is a silent wrong number); and once closed, the drive
is off (commanded, or stopped by the amplifier's watchdog) within the watchdog's time.

The emulator's Modbus server against hostile requests: :func:`check_server` sends drawn
bytes (well-framed requests with any function code, address, count and values, and
broken frames) on a raw socket; the server must then still answer a proper client on a
new connection, and its setpoints stay inside the amplifier's own ranges.
"""

from __future__ import annotations

import contextlib
import math
import random
import socket
import struct
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from hypothesis import strategies as st

from drivers.amplifier_registers import (
    DEVICE_MAX_AMPLITUDE_UM,
    DEVICE_MAX_FREQUENCY_MHZ,
    DEVICE_MAX_RAMP_RATE_UM_S,
    MODEL_CODE,
    Holding,
    Input,
)
from drivers.interfaces import DeviceError
from drivers.limits import ShakerLimits
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.shaker_response import ShakerDynamics, ShakerResponse
from harness.fuzz.boundaries import SLOW_S, BadAnswerError, one_line_naming

LIMITS = ShakerLimits(
    max_amplitude_m=0.005,
    min_frequency_hz=0.5,
    max_frequency_hz=40.0,
    min_ramp_rate_m_s=1e-5,
    max_ramp_rate_m_s=0.05,
)
TIMEOUT_S = 0.3  # the driver's reply timeout here
WATCHDOG_S = 0.5
FATES = (
    "pass", "delay", "drop", "close", "truncate", "unit", "tid", "exception", "flip",
    "garbage", "length", "values", "short", "huge", "reset",
)


def amplifier() -> AmplifierEmulator:
    """A started amplifier emulator (a quick plant: it follows the setpoints in ms)."""
    quick = ShakerDynamics(frequency_slew_hz_s=200.0, amplitude_tau_s=0.01, frequency_tau_s=0.01)
    return AmplifierEmulator(AmplifierFirmware(ShakerResponse(quick))).start()


def reset(firmware: AmplifierFirmware) -> None:
    """Drive off, faults cleared: the state every example starts from."""
    firmware.write(int(Holding.ENABLE), [0])
    firmware.write(int(Holding.COMMAND), [1])
    firmware.write(int(Holding.AMPLITUDE_UM), [0])


# -- a proxy that mangles the amplifier's replies ---------------------------------------------


HEARTBEAT_ADDRESS = struct.pack(">H", int(Holding.HEARTBEAT))


class ManglingProxy:
    """Loopback TCP in front of the amplifier: the n-th reply meets ``fates[n]`` (then
    "pass"), with the fate's parameters drawn from ``seed``.  Replies to the heartbeat
    (written from the driver's own thread, whenever its period says) pass and are not
    counted, so that which request meets which fate does not depend on timing."""

    def __init__(self, server_port: int, fates: list[str], seed: int) -> None:
        self.server_port = server_port
        self.fates = list(fates)
        self.random = random.Random(seed)
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.1)
        self.port = self.listener.getsockname()[1]
        self.stop = threading.Event()
        self.threads: list[threading.Thread] = []
        self.accepting = threading.Thread(target=self._accept, daemon=True)
        self.accepting.start()

    def close(self) -> None:
        self.stop.set()
        self.accepting.join(5)
        for thread in self.threads:
            thread.join(5)
        self.listener.close()

    def _accept(self) -> None:
        while not self.stop.is_set():
            try:
                client, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            thread = threading.Thread(target=self._serve, args=(client,), daemon=True)
            thread.start()
            self.threads.append(thread)

    def _fate(self) -> str:
        return self.fates.pop(0) if self.fates else "pass"

    def _serve(self, client: socket.socket) -> None:
        client.settimeout(0.1)
        with client, socket.create_connection(("127.0.0.1", self.server_port), 2) as server:
            server.settimeout(2.0)
            while not self.stop.is_set():
                try:
                    request = _read_frame(client, self.stop)
                    if request is None:
                        return
                    server.sendall(request)
                    reply = _read_frame(server, self.stop)
                except OSError:
                    return
                if reply is None:
                    return
                heartbeat = request[7] in (6, 16) and request[8:10] == HEARTBEAT_ADDRESS
                fate = "pass" if heartbeat else self._fate()  # the order of the driver's own
                if fate == "reset":  # closed with a TCP reset, as a rebooting controller does
                    client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                if fate in ("close", "reset"):
                    return
                mangled = self._mangle(fate, request, reply)
                with contextlib.suppress(OSError):
                    client.sendall(mangled)

    def _mangle(self, fate: str, request: bytes, reply: bytes) -> bytes:
        r = self.random
        data = bytearray(reply)
        match fate:
            case "delay":
                self.stop.wait(r.choice([0.05, 0.2, TIMEOUT_S * 1.5, 1.0]))
            case "drop":
                return b""
            case "truncate":
                return bytes(data[: r.randrange(0, len(data))])
            case "unit":
                data[6] = (data[6] + r.randrange(1, 256)) % 256
            case "tid":
                data[0:2] = struct.pack(">H", (struct.unpack(">H", data[0:2])[0] + 1) % 65536)
            case "exception":
                code = r.choice([1, 2, 3, 4, 5, 6, 8, 10, 11, 0, 0x7F])
                pdu = struct.pack(">HBBB", 3, data[6], request[7] | 0x80, code)
                data = bytearray(data[:4]) + pdu
            case "flip":
                at = r.randrange(7, len(data))
                data[at] ^= 1 << r.randrange(8)
            case "garbage":
                junk = bytes(r.randrange(256) for _ in range(r.randrange(1, 12)))
                data = data + junk if r.random() < 0.5 else bytearray(junk) + data
            case "length":
                data[4:6] = struct.pack(">H", r.choice([0, 1, 2, len(data), 300, 65535]))
            case "values" if request[7] in (3, 4) and len(data) > 9:
                for at in range(9, len(data)):
                    data[at] = r.randrange(256)
            case "huge" if request[7] in (3, 4) and len(data) > 9:  # every word 0xFFFF
                data[9:] = b"\xff" * (len(data) - 9)
            case "short" if request[7] in (3, 4) and len(data) > 11:  # one register only
                tid, protocol, _length = struct.unpack(">HHH", data[:6])
                data = bytearray(struct.pack(">HHHB", tid, protocol, 5, data[6]))
                data += bytes([request[7], 2]) + reply[9:11]
        return bytes(data)


def _read_frame(sock: socket.socket, stop: threading.Event) -> bytes | None:
    """One Modbus TCP frame (MBAP header and PDU), or None when the peer closed."""
    header = _read_exactly(sock, 7, stop)
    if header is None:
        return None
    (length,) = struct.unpack(">H", header[4:6])
    body = _read_exactly(sock, max(0, length - 1), stop)
    return None if body is None else header + body


def _read_exactly(sock: socket.socket, n: int, stop: threading.Event) -> bytes | None:
    data = b""
    while len(data) < n:
        if stop.is_set():
            return None
        try:
            part = sock.recv(n - len(data))
        except TimeoutError:
            continue
        if not part:
            return None
        data += part
    return data


# -- the driver against it ---------------------------------------------------------------------

OPERATIONS = (
    "measured", "status", "setpoints", "amplitude", "frequency", "enable", "disable",
    "clear_faults", "stop",
)


@dataclass(frozen=True)
class DriverCase:
    """Fates of the replies in order, the proxy's seed, the driver's operations in order,
    and whether the driver reconnects on its own."""

    fates: tuple[str, ...]
    seed: int
    operations: tuple[str, ...]
    reconnect: bool


def driver_cases(reconnect: bool | None = None) -> st.SearchStrategy[DriverCase]:
    """Cases for :func:`check_driver`; ``reconnect`` fixed, or drawn when None (a driver
    that reconnects reopens the link from its heartbeat thread, whose requests then meet
    fates in an order that depends on timing: the suite fixes it off)."""
    return st.builds(
        DriverCase,
        st.lists(st.sampled_from(FATES), max_size=16).map(tuple),
        st.integers(0, 2**32 - 1),
        st.lists(st.sampled_from(OPERATIONS), min_size=1, max_size=8).map(tuple),
        st.booleans() if reconnect is None else st.just(reconnect),
    )


def _operate(shaker: ShakerAmplifier, operation: str) -> None:
    match operation:
        case "measured":
            drive = shaker.measured()
            _possible("measured()", drive.frequency_hz, drive.amplitude_m)
        case "status":
            shaker.status()  # never raises, by its contract
        case "setpoints":
            held = shaker.setpoints()
            _possible("setpoints()", held.frequency_hz, held.amplitude_m, held.ramp_rate_m_s)
        case "amplitude":
            shaker.amplitude_m = 0.001
        case "frequency":
            shaker.frequency_hz = 10.0
        case "enable":
            shaker.enabled = True
        case "disable":
            shaker.enabled = False
        case "clear_faults":
            shaker.clear_faults()
        case "stop":
            shaker.stop()


def _possible(what: str, frequency_hz: float, amplitude_m: float, rate_m_s: float = 0.0) -> None:
    """A reading the amplifier can give: finite and inside its own ranges (a reply that
    says otherwise is garbled, and passing it on would be a silent wrong number)."""
    numbers = (frequency_hz, amplitude_m, rate_m_s)
    if not all(isinstance(x, float) and math.isfinite(x) and x >= 0 for x in numbers) or (
        frequency_hz > DEVICE_MAX_FREQUENCY_MHZ / 1000.0
        or amplitude_m > DEVICE_MAX_AMPLITUDE_UM / 1e6
        or rate_m_s > DEVICE_MAX_RAMP_RATE_UM_S / 1e6
    ):
        raise BadAnswerError(
            f"{what} passed on a reading the amplifier cannot give: {frequency_hz} Hz, "
            f"{amplitude_m} m, {rate_m_s} m/s"
        )


@contextlib.contextmanager
def _timed(what: str) -> Iterator[None]:
    started = time.perf_counter()
    yield
    took = time.perf_counter() - started
    if took > SLOW_S:
        raise BadAnswerError(f"{what} answered after {took:.1f} s (limit {SLOW_S:g} s)")


def check_driver(emulator: AmplifierEmulator, case: DriverCase) -> None:
    """The driver through a mangling proxy: DeviceError in one line or a result, in time;
    the drive off once closed."""
    firmware = emulator.firmware
    reset(firmware)
    assert emulator.port is not None
    proxy = ManglingProxy(emulator.port, list(case.fates), case.seed)
    backend = ModbusTcpBackend("127.0.0.1", proxy.port, timeout_s=TIMEOUT_S, retries=0)
    shaker = ShakerAmplifier(backend, LIMITS, watchdog_s=WATCHDOG_S, reconnect=case.reconnect)
    try:
        try:
            with _timed("connect()"):
                shaker.connect()
        except DeviceError as error:
            one_line_naming(error)
            return
        shaker.ramp_rate_m_s = 0.05 if shaker.connected else shaker.ramp_rate_m_s
        for operation in case.operations:
            try:
                with _timed(operation):
                    _operate(shaker, operation)
            except DeviceError as error:
                one_line_naming(error)
    except DeviceError as error:  # the ramp rate's write, before the operations
        one_line_naming(error)
    finally:
        with _timed("close()"):
            shaker.close()
        proxy.close()
    # closed (or its link lost): the drive is off, by the driver or by the watchdog
    deadline = time.monotonic() + WATCHDOG_S + 1.0
    while firmware.enabled and time.monotonic() < deadline:
        firmware.service()
        time.sleep(0.02)
    if firmware.enabled:
        raise BadAnswerError("the drive is still on after close() and the watchdog's time")


# -- hostile requests to the emulator's server ---------------------------------------------------


@st.composite
def hostile_requests(draw: st.DrawFn) -> list[bytes]:
    """Requests a broken or hostile client might send: well-framed with any content, or not."""
    out = []
    for _ in range(draw(st.integers(1, 8))):
        tid = draw(st.integers(0, 65535))
        unit = draw(st.sampled_from([0, 1, 2, 247, 255]))
        function = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 15, 16, 17, 23, 43, 0, 0x80, 255]))
        address = draw(st.integers(0, 65535))
        count = draw(st.integers(0, 300))
        body = struct.pack(">HH", address, count)
        if function in (6, 16, 23):
            words = draw(st.lists(st.integers(0, 65535), max_size=8))
            if function == 6:
                body = struct.pack(">HH", address, words[0] if words else count)
            else:
                body = (
                    struct.pack(">HHB", address, len(words), draw(st.integers(0, 255)))
                    + b"".join(struct.pack(">H", w) for w in words)
                )
        body = draw(st.one_of(st.just(body), st.binary(max_size=20)))
        pdu = bytes([function]) + body
        length = draw(st.one_of(st.just(len(pdu) + 1), st.integers(0, 300)))
        frame = struct.pack(">HHHB", tid, draw(st.sampled_from([0, 0, 1])), length, unit) + pdu
        match draw(st.sampled_from(["whole", "whole", "cut", "garbage"])):
            case "cut":
                frame = frame[: draw(st.integers(0, len(frame)))]
            case "garbage":
                frame = draw(st.binary(min_size=1, max_size=40))
        out.append(frame)
    return out


def check_server(emulator: AmplifierEmulator, requests: list[bytes]) -> None:
    """Hostile bytes on one connection; then a proper client on a new one must be served,
    and the setpoints stay in the amplifier's ranges."""
    assert emulator.port is not None
    reset(emulator.firmware)
    with socket.create_connection(("127.0.0.1", emulator.port), 2) as raw:
        raw.settimeout(0.05)
        for frame in requests:
            with contextlib.suppress(OSError):
                raw.sendall(frame)
                with contextlib.suppress(TimeoutError):
                    raw.recv(512)
    backend = ModbusTcpBackend("127.0.0.1", emulator.port, timeout_s=1.0, retries=0)
    started = time.perf_counter()
    try:
        backend.open()
        model = backend.read_input_registers(int(Input.MODEL_CODE), 1)
    except DeviceError as error:
        raise BadAnswerError(f"the server no longer answers a proper client: {error}") from None
    finally:
        backend.close()
    if model != [MODEL_CODE] or time.perf_counter() - started > SLOW_S:
        raise BadAnswerError(f"after hostile requests the server answered {model} slowly or wrong")
    held = emulator.firmware.read_holding(0, 3)
    frequency_mhz, amplitude_um = held[0] << 16 | held[1], held[2]
    if frequency_mhz > DEVICE_MAX_FREQUENCY_MHZ or amplitude_um > DEVICE_MAX_AMPLITUDE_UM:
        raise BadAnswerError(f"hostile writes set the drive outside its range: {held}")
