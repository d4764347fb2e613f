"""An emulated bench function generator serving SCPI on a loopback TCP socket (as port 5025).

It answers the subset of SCPI the SCPI shaker driver (:mod:`drivers.scpi_shaker`) uses,
as a Keysight 33500B or Rigol DG1000Z does: ``*IDN?``, ``*CLS``, ``*RST``, ``*OPC?``,
``[SOURce[1]:]FREQuency``, ``VOLTage`` (in Vpp), ``VOLTage:UNIT``, ``VOLTage:OFFSet``,
``FUNCtion``, ``OUTPut[1] ON|OFF`` and ``SYSTem:ERRor?``, long or short forms, several
commands on one line separated by ``;``.  Out-of-range values are clipped and queue
``-222,"Data out of range"``, as those generators do.

Faults can be switched on at run time (:class:`GeneratorFault`): no answer, an error
queued after every setting, an amplitude silently clipped, a frequency ignored.

The optional *disconnect watchdog* (on by default) turns the output off when the host
connection that turned it on closes (the front panel's Output key is not watched).  It
is a property of this emulator only: a real bench generator keeps its output on when
the host dies (docs/scpi_generator.md says what a lab must add).  Everything is
bounded: connections, line length, error queue and log.
"""

from __future__ import annotations

import contextlib
import enum
import select
import socket
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

MAX_CLIENTS = 4  # further connections are closed at once
MAX_LINE_BYTES = 4096  # a longer line is discarded with -223
ERROR_QUEUE_LENGTH = 20  # as the 33500B; the last entry becomes -350 on overflow
LOG_LENGTH = 10_000  # command lines kept for inspection
DEFAULT_IDENTITY = "impact-rig,Emulated SCPI generator,SIM00001,1.0"

# long SCPI node names -> the short form (the short form is accepted as is)
_LONG = {
    "SOURCE": "SOUR",
    "FREQUENCY": "FREQ",
    "VOLTAGE": "VOLT",
    "OUTPUT": "OUTP",
    "FUNCTION": "FUNC",
    "OFFSET": "OFFS",
    "SYSTEM": "SYST",
    "ERROR": "ERR",
    "FIXED": "FIX",
    "NEXT": "NEXT",
}
_FUNCTIONS = {"SIN": "SIN", "SINUSOID": "SIN", "SQU": "SQU", "SQUARE": "SQU", "RAMP": "RAMP"}
_UNITS = ("VPP", "VRMS", "DBM")


class GeneratorFault(enum.Enum):
    """Faults of the emulated generator, switchable at run time."""

    NONE = "none"
    NO_ANSWER = "no_answer"  # commands are carried out, queries never answered: the host times out
    QUEUE_ERROR = "queue_error"  # every setting command also queues -221,"Settings conflict"
    CLIP_AMPLITUDE = "clip_amplitude"  # amplitudes above clip_vpp silently held at clip_vpp
    IGNORE_FREQUENCY = "ignore_frequency"  # frequency commands accepted without error, not applied


@dataclass(frozen=True)
class GeneratorState:
    """What the generator's channel 1 holds and outputs."""

    frequency_hz: float = 1000.0
    amplitude_vpp: float = 0.1
    offset_v: float = 0.0
    function: str = "SIN"
    unit: str = "VPP"
    output: bool = False


class _CommandError(Exception):
    """A SCPI error to queue: ``code`` and its standard message."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


class ScpiGeneratorEmulator:
    """A function generator on ``host:port`` (``port=0``: a free port, read
    :attr:`~ScpiGeneratorEmulator.port`).

    ``on_change`` is called with the new :class:`GeneratorState` after every change (the
    virtual rig moves its shaker with it).  ``output_off_on_disconnect`` is the emulator's
    watchdog (see the module docstring).
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        identity: str = DEFAULT_IDENTITY,
        max_frequency_hz: float = 30e6,
        min_vpp: float = 0.002,
        max_vpp: float = 20.0,
        output_off_on_disconnect: bool = True,
        on_change: Callable[[GeneratorState], None] | None = None,
    ) -> None:
        self.host = host
        self._requested_port = port
        self.port: int | None = None  #: the TCP port served, once started
        self.identity = identity
        self.max_frequency_hz = max_frequency_hz
        self.min_vpp, self.max_vpp = min_vpp, max_vpp
        self.output_off_on_disconnect = output_off_on_disconnect
        self.on_change = on_change
        self.fault = GeneratorFault.NONE
        self.clip_vpp = 1.0  # for GeneratorFault.CLIP_AMPLITUDE
        self.watchdog_trips = 0  # how often the disconnect watchdog turned the output off
        self._state = GeneratorState()
        self._errors: deque[tuple[int, str]] = deque()
        self._log: deque[str] = deque(maxlen=LOG_LENGTH)
        self._changed = threading.Condition()
        self._listener: socket.socket | None = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        self._accept_thread: threading.Thread | None = None
        self._clients: dict[socket.socket, threading.Thread] = {}
        self._output_owner: socket.socket | None = None  # the connection that turned it on
        self._running = False

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> ScpiGeneratorEmulator:
        """Listen and serve; returns once connections are accepted."""
        if self._running:
            return self
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((self.host, self._requested_port))
            listener.listen(MAX_CLIENTS)
        except OSError as error:
            listener.close()
            raise RuntimeError(
                f"SCPI generator emulator could not listen on {self.host}:"
                f"{self._requested_port}: {error}"
            ) from None
        self._listener = listener
        self.port = listener.getsockname()[1]
        self._wake_r, self._wake_w = socket.socketpair()
        self._running = True
        self._accept_thread = threading.Thread(
            target=self._accept, name="scpi-generator", daemon=True
        )
        self._accept_thread.start()
        return self

    def stop(self) -> None:
        """Stop serving, close every connection and the port; safe to call twice."""
        if not self._running:
            return
        self._running = False
        assert self._wake_w is not None
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")
        if self._accept_thread is not None:
            self._accept_thread.join(5.0)
        with self._changed:
            clients = list(self._clients.items())
        for conn, _ in clients:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
        for _, thread in clients:
            thread.join(5.0)
        for sock in (self._listener, self._wake_r, self._wake_w):
            if sock is not None:
                sock.close()
        self._listener = self._wake_r = self._wake_w = None

    def __enter__(self) -> ScpiGeneratorEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def resource(self) -> str:
        """The VISA resource string of this generator (raw socket)."""
        return f"TCPIP::{self.host}::{self.port}::SOCKET"

    # ------------------------------------------------------------------ what it holds and saw

    @property
    def state(self) -> GeneratorState:
        """The channel's settings and output now."""
        with self._changed:
            return self._state

    @property
    def errors(self) -> list[tuple[int, str]]:
        """The error queue, oldest first (not consumed)."""
        with self._changed:
            return list(self._errors)

    @property
    def received(self) -> list[str]:
        """Command lines received (the last LOG_LENGTH), oldest first."""
        with self._changed:
            return list(self._log)

    @property
    def connections(self) -> int:
        """Host connections open now."""
        with self._changed:
            return len(self._clients)

    def clear_log(self) -> None:
        """Forget the received lines (start of a test step)."""
        with self._changed:
            self._log.clear()

    def wait_for(self, condition: Callable[[GeneratorState], bool], timeout_s: float) -> bool:
        """Wait (at most ``timeout_s``) until ``condition(state)`` holds; True if it did."""
        with self._changed:
            return self._changed.wait_for(lambda: condition(self._state), timeout_s)

    def set_output(self, on: bool) -> None:
        """The front panel's Output key."""
        with self._changed:
            self._output_owner = None
            self._set(output=bool(on))

    # ------------------------------------------------------------------ server

    def _accept(self) -> None:
        assert self._listener is not None and self._wake_r is not None
        while self._running:
            ready, _, _ = select.select([self._listener, self._wake_r], [], [])
            if self._wake_r in ready or not self._running:
                return
            try:
                conn, _ = self._listener.accept()
            except OSError:
                continue
            with self._changed:
                if len(self._clients) >= MAX_CLIENTS:
                    conn.close()
                    continue
                thread = threading.Thread(
                    target=self._serve, args=(conn,), name="scpi-generator-client", daemon=True
                )
                self._clients[conn] = thread
            thread.start()

    def _serve(self, conn: socket.socket) -> None:
        buffer = b""
        discarding = False
        try:
            while True:
                try:
                    chunk = conn.recv(4096)
                except OSError:
                    break
                if not chunk:
                    break
                buffer += chunk
                while b"\n" in buffer:
                    line, buffer = buffer.split(b"\n", 1)
                    if discarding or len(line) > MAX_LINE_BYTES:
                        if not discarding:
                            with self._changed:
                                self._queue(-223, "Too much data")
                        discarding = False
                        continue
                    reply = self._line(line.decode("ascii", "replace").strip(), conn)
                    if reply is not None:
                        with contextlib.suppress(OSError):
                            conn.sendall(reply.encode("ascii") + b"\n")
                if len(buffer) > MAX_LINE_BYTES:
                    buffer, discarding = b"", True
                    with self._changed:
                        self._queue(-223, "Too much data")
        finally:
            conn.close()
            with self._changed:
                self._clients.pop(conn, None)
                self._changed.notify_all()  # whoever waits on the connections
                if self._output_owner is conn:
                    self._output_owner = None
                    if self.output_off_on_disconnect and self._state.output:
                        self.watchdog_trips += 1
                        self._set(output=False)

    # ------------------------------------------------------------------ SCPI

    def _line(self, line: str, client: socket.socket | None = None) -> str | None:
        """Carry out one line of commands from ``client``; the replies to its queries, or None."""
        if not line:
            return None
        replies: list[str] = []
        with self._changed:
            self._log.append(line)
            for part in line.split(";"):
                part = part.strip()
                if not part:
                    continue
                try:
                    reply = self._command(part, client)
                except _CommandError as error:
                    self._queue(error.code, str(error))
                    continue
                if reply is not None:
                    replies.append(reply)
            if self.fault is GeneratorFault.NO_ANSWER or not replies:
                return None
            return ";".join(replies)

    def _command(self, text: str, client: socket.socket | None) -> str | None:  # noqa: C901
        header, _, argument = text.partition(" ")
        argument = argument.strip()
        query = header.endswith("?")
        nodes = _nodes(header.rstrip("?"))
        if nodes == ("*IDN",) and query:
            return self.identity
        if nodes == ("*OPC",) and query:
            return "1"
        if nodes == ("*CLS",) and not query:
            self._errors.clear()
            return None
        if nodes == ("*RST",) and not query:
            self._output_owner = None
            self._set(**vars(GeneratorState()))
            return None
        if nodes in (("SYST", "ERR"), ("SYST", "ERR", "NEXT")) and query:
            code, message = self._errors.popleft() if self._errors else (0, "No error")
            return f'{code:+d},"{message}"'
        if nodes and nodes[0] == "OUTP" and len(nodes) == 1:
            if query:
                return "1" if self._state.output else "0"
            on = _word(argument, {"ON": True, "1": True, "OFF": False, "0": False})
            self._output_owner = client if on else None
            self._set(output=on)
            return None
        if nodes in (("FREQ",), ("FREQ", "FIX")):
            if query:
                return _number(self._state.frequency_hz)
            value = self._clip(_float(argument), 1e-6, self.max_frequency_hz)
            self._setting_done()
            if self.fault is not GeneratorFault.IGNORE_FREQUENCY:
                self._set(frequency_hz=value)
            return None
        if nodes == ("VOLT",):
            if query:
                return _number(self._state.amplitude_vpp)
            value = self._clip(_float(argument), self.min_vpp, self.max_vpp)
            if self.fault is GeneratorFault.CLIP_AMPLITUDE:
                value = min(value, self.clip_vpp)
            self._setting_done()
            self._set(amplitude_vpp=value)
            return None
        if nodes == ("VOLT", "UNIT"):
            if query:
                return self._state.unit
            self._set(unit=_word(argument, {u: u for u in _UNITS}))
            self._setting_done()
            return None
        if nodes == ("VOLT", "OFFS"):
            if query:
                return _number(self._state.offset_v)
            self._set(offset_v=self._clip(_float(argument), -self.max_vpp / 2, self.max_vpp / 2))
            self._setting_done()
            return None
        if nodes == ("FUNC",):
            if query:
                return self._state.function
            self._set(function=_word(argument, _FUNCTIONS))
            self._setting_done()
            return None
        raise _CommandError(-113, "Undefined header")

    def _clip(self, value: float, low: float, high: float) -> float:
        if not low <= value <= high:
            self._queue(-222, "Data out of range")
            return min(max(value, low), high)
        return value

    def _setting_done(self) -> None:
        if self.fault is GeneratorFault.QUEUE_ERROR:
            self._queue(-221, "Settings conflict")

    def _queue(self, code: int, message: str) -> None:
        if len(self._errors) >= ERROR_QUEUE_LENGTH:
            self._errors[-1] = (-350, "Queue overflow")
            return
        self._errors.append((code, message))

    def _set(self, **changes: object) -> None:
        """Change the state (caller holds the lock) and tell whoever waits or listens."""
        new = replace(self._state, **changes)
        if new == self._state:
            return
        self._state = new
        self._changed.notify_all()
        if self.on_change is not None:
            self.on_change(new)


def _nodes(header: str) -> tuple[str, ...]:
    """``:SOURce1:VOLTage:UNIT`` -> ('VOLT', 'UNIT'): short forms; suffix 1 and SOUR dropped."""
    out: list[str] = []
    for raw in header.upper().lstrip(":").split(":"):
        name = raw.rstrip("0123456789") if not raw.startswith("*") else raw
        suffix = raw[len(name) :]
        if suffix not in ("", "1"):
            raise _CommandError(-114, "Header suffix out of range")
        out.append(_LONG.get(name, name))
    if out and out[0] == "SOUR":
        out = out[1:]
    return tuple(out)


def _float(argument: str) -> float:
    if not argument:
        raise _CommandError(-109, "Missing parameter")
    try:
        value = float(argument)
    except ValueError:
        raise _CommandError(-104, "Data type error") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise _CommandError(-104, "Data type error")
    return value


def _word(argument: str, choices: dict[str, object]) -> object:
    if not argument:
        raise _CommandError(-109, "Missing parameter")
    key = argument.upper()
    if key not in choices:
        raise _CommandError(-224, "Illegal parameter value")
    return choices[key]


def _number(value: float) -> str:
    """A number as the 33500B answers it: ``+1.00000000000000E+01``."""
    return f"{value:+.14E}"
