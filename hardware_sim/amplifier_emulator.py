"""The shaker amplifier as a real pymodbus server: Modbus TCP on loopback, and Modbus RTU on a pty.

The register logic is :class:`AmplifierFirmware`; this module only puts it on the
wire, records what it received (for protocol tests) and injects transport faults
(no reply, exception replies).  The server runs its asyncio loop in a background
thread, so tests and the ``sim-rig`` command use it like a device on the bench.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import os
import select
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from pymodbus.constants import ExcCodes
from pymodbus.pdu import ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.amplifier_registers import HOLDING_COUNT, INPUT_COUNT
from hardware_sim.amplifier_firmware import AmplifierFirmware, RegisterAccessError

WATCHDOG_POLL_S = 0.02
# a gap between two of the watchdog loop's turns longer than this is the emulator's own stall
STALL_S = 5 * WATCHDOG_POLL_S
START_TIMEOUT_S = 10.0
LOG_LENGTH = 10_000  # requests kept for inspection
_READ_INPUT, _READ_HOLDING = 4, 3
_WRITES = (6, 16)

# pymodbus logs every refused request and deprecation at WARNING/ERROR; an emulator
# answering exceptions on purpose should not flood the console.
if logging.getLogger("pymodbus").level == logging.NOTSET:  # unless the application chose
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


class TransportFault(enum.Enum):
    """Faults of the link or the controller's communication, switchable at run time."""

    NONE = "none"
    NO_REPLY = "no_reply"  # requests are swallowed: the host times out
    DEVICE_FAILURE = "device_failure"  # every request answers exception 0x04
    BUSY = "busy"  # every request answers exception 0x06


_EXCEPTION_FOR = {
    TransportFault.DEVICE_FAILURE: ExcCodes.DEVICE_FAILURE,
    TransportFault.BUSY: ExcCodes.DEVICE_BUSY,
}


@dataclass(frozen=True)
class ReceivedRequest:
    """One request PDU the emulator received (whether or not it answered)."""

    function_code: int
    address: int
    count: int
    values: tuple[int, ...]

    @property
    def is_write(self) -> bool:
        """True for FC6 / FC16."""
        return self.function_code in _WRITES


class AwakeClock:
    """The firmware's watchdog clock inside an emulator: the wall clock ``inner`` less the
    time the emulator's loop stood still (a gap of more than ``stall_s`` between two
    ``tick`` calls, less that much).

    A real amplifier's firmware never stalls; this one shares a process and its cores with
    the host, and a loaded machine or a thread holding the GIL stops both.  Counted as the
    host's silence, such a stall tripped the watchdog of a host that was heartbeating
    (the guide's ``sweep --sim`` under a loaded test run): the heartbeats the host had sent
    waited in the socket while the first request after the stall checked the watchdog.
    A host silent while the emulator runs is still timed to the millisecond."""

    def __init__(self, inner: Callable[[], float] = time.monotonic,
                 stall_s: float = STALL_S) -> None:
        self._inner = inner
        self._stall_s = stall_s
        self._lock = threading.Lock()
        self._last = inner()
        self._lost = 0.0

    def _unseen(self, now: float) -> float:
        gap = now - self._last
        return gap - self._stall_s if gap > self._stall_s else 0.0

    def tick(self) -> None:
        """The emulator's loop is running (called every turn of its watchdog loop)."""
        with self._lock:
            now = self._inner()
            self._lost += self._unseen(now)
            self._last = now

    def __call__(self) -> float:
        with self._lock:
            now = self._inner()
            return now - self._lost - self._unseen(now)


class AmplifierEmulator:
    """A pymodbus server answering as the shaker amplifier of docs/amplifier_registers.md.

    ``port=0`` picks a free TCP port (read it from :attr:`port`).  ``rtu=True``
    also serves Modbus RTU on a pseudo-terminal; clients open :attr:`rtu_path`.
    ``tcp=False`` serves RTU only.
    """

    def __init__(
        self,
        firmware: AmplifierFirmware | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        tcp: bool = True,
        rtu: bool = False,
        rtu_baudrate: int = 19200,
    ) -> None:
        self.firmware = firmware or AmplifierFirmware()
        self._clock = AwakeClock(self.firmware.wall_clock)
        self.firmware.wall_clock = self._clock
        self.host = host
        self._requested_port = port
        self._tcp, self._rtu = tcp, rtu
        self._baudrate = rtu_baudrate
        self.port: int | None = None  #: the TCP port served, once started
        self.rtu_path: str | None = None  #: the RTU pseudo-terminal's path, once started
        self.fault = TransportFault.NONE
        # bounded: a sim-rig left running for days must not grow without end
        self._requests: deque[ReceivedRequest] = deque(maxlen=LOG_LENGTH)
        self._log_lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._servers: list = []
        self._bridge: _PtyBridge | None = None
        self._started = threading.Event()
        self._start_error: BaseException | None = None
        self._watchdog_task: asyncio.Task[None] | None = None

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> AmplifierEmulator:
        """Start serving; returns once the endpoints accept connections."""
        if self._thread is not None:
            return self
        if self._rtu:
            self._bridge = _PtyBridge()
            self.rtu_path = self._bridge.client_path
        self._thread = threading.Thread(target=self._run, name="amplifier-emulator", daemon=True)
        self._thread.start()
        if not self._started.wait(START_TIMEOUT_S):
            self._start_error = TimeoutError(f"not serving after {START_TIMEOUT_S:g} s")
        if self._start_error is not None:
            where = f"Modbus TCP {self.host}:{self._requested_port}" if self._tcp else "Modbus RTU"
            self.stop()
            raise RuntimeError(
                f"amplifier emulator could not start on {where}: {self._start_error}"
            )
        return self

    def stop(self) -> None:
        """Stop serving and release the port and the pty; safe to call twice."""
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None and thread.is_alive():
            with contextlib.suppress(RuntimeError, TimeoutError):
                asyncio.run_coroutine_threadsafe(self._shutdown(), loop).result(5.0)
            thread.join(5.0)
        self._thread = None
        if self._bridge is not None:
            self._bridge.close()
            self._bridge = None

    def __enter__(self) -> AmplifierEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def endpoint(self) -> str:
        """``host:port`` of the TCP server."""
        return f"{self.host}:{self.port}"

    # ------------------------------------------------------------------ what it saw

    @property
    def requests(self) -> list[ReceivedRequest]:
        """The requests received (the last LOG_LENGTH), oldest first."""
        with self._log_lock:
            return list(self._requests)

    def clear_log(self) -> None:
        """Forget the received requests (start of a test step)."""
        with self._log_lock:
            self._requests.clear()

    # ------------------------------------------------------------------ server internals

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as error:  # reported to start()
            self._start_error = error
        finally:
            self._started.set()
        try:
            loop.run_forever()
        finally:
            loop.close()

    def _device(self) -> SimDevice:
        def block(count: int) -> list[SimData]:
            return [SimData(0, count=count, values=0, datatype=DataType.REGISTERS)]

        def bits() -> list[SimData]:
            return [SimData(0, values=False, datatype=DataType.BITS)]

        # id 0 answers every unit id, as most TCP controllers do.
        return SimDevice(
            id=0,
            simdata=(bits(), bits(), block(HOLDING_COUNT), block(INPUT_COUNT)),
            action=self._action,
        )

    async def _serve(self) -> None:
        if self._tcp:
            tcp = ModbusTcpServer(
                self._device(),
                address=(self.host, self._requested_port),
                trace_pdu=self._trace_pdu,
            )
            await tcp.serve_forever(background=True)
            self.port = int(tcp.transport.sockets[0].getsockname()[1])
            self._servers.append(tcp)
        if self._rtu and self._bridge is not None:
            rtu = ModbusSerialServer(
                self._device(),
                port=self._bridge.server_path,
                baudrate=self._baudrate,
                trace_pdu=self._trace_pdu,
            )
            await rtu.serve_forever(background=True)
            self._servers.append(rtu)
        self._watchdog_task = asyncio.get_running_loop().create_task(self._watchdog())

    async def _watchdog(self) -> None:
        # The firmware also checks on every request; this catches a host that went silent.
        while True:
            self._clock.tick()
            self.firmware.service()
            await asyncio.sleep(WATCHDOG_POLL_S)

    async def _shutdown(self) -> None:
        # also after a failed start: the watchdog may not exist, some servers may
        if self._watchdog_task is not None:
            self._watchdog_task.cancel()
        for server in self._servers:
            await server.shutdown()
        self._servers.clear()
        asyncio.get_running_loop().call_soon(asyncio.get_running_loop().stop)

    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU | None:
        if sending:
            return pdu
        values = tuple(getattr(pdu, "registers", None) or ())
        count = getattr(pdu, "count", 0) or len(values)
        with self._log_lock:
            self._requests.append(ReceivedRequest(pdu.function_code, pdu.address, count, values))
        if self.fault is TransportFault.NO_REPLY:
            return None  # swallowed: never executed, never answered
        return pdu

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if self.fault in _EXCEPTION_FOR:
            return _EXCEPTION_FOR[self.fault]
        offset = address - start_address
        try:
            if function_code == _READ_INPUT:
                registers[offset : offset + count] = self.firmware.read_input(address, count)
            elif function_code == _READ_HOLDING:
                registers[offset : offset + count] = self.firmware.read_holding(address, count)
            elif function_code in _WRITES:
                if set_values is not None:
                    self.firmware.write(address, [int(v) for v in set_values])
                # else: pymodbus reads back what was written to echo it (FC6 reply)
            else:
                return ExcCodes.ILLEGAL_FUNCTION
        except RegisterAccessError as error:
            return ExcCodes(error.code)
        return None


class _PtyBridge:
    """Two pseudo-terminals joined back to back, like a null-modem cable.

    The server (pymodbus opens serial ports by path) opens one slave, the client
    the other; a thread copies bytes between the two masters.
    """

    def __init__(self) -> None:
        self._server_master, server_slave = os.openpty()
        self._client_master, client_slave = os.openpty()
        self.server_path = os.ttyname(server_slave)
        self.client_path = os.ttyname(client_slave)
        for fd in (server_slave, client_slave):
            tty.setraw(fd)  # no echo or line editing: Modbus bytes pass untouched
        # Keep the slaves open ourselves so the masters never see a hang-up between sessions.
        self._slaves = (server_slave, client_slave)
        for fd in (self._server_master, self._client_master):
            os.set_blocking(fd, False)  # a side nobody reads must not block the copying
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._copy, name="rtu-pty-bridge", daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        peer = {self._server_master: self._client_master, self._client_master: self._server_master}
        while True:
            ready, _, _ = select.select([*peer, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                if data:
                    # what does not fit is lost, as on a real line nobody reads
                    with contextlib.suppress(BlockingIOError):
                        os.write(peer[fd], data)

    def close(self) -> None:
        """Stop copying and close both pseudo-terminals."""
        os.write(self._stop_w, b"x")
        self._thread.join(2.0)
        if self._thread.is_alive():
            return  # never close descriptors under a thread still using them (numbers get reused)
        for fd in (
            self._server_master,
            self._client_master,
            *self._slaves,
            self._stop_r,
            self._stop_w,
        ):
            with contextlib.suppress(OSError):
                os.close(fd)
