"""DAQ backend over a serial port (USB CDC, e.g. /dev/ttyACM0), speaking docs/daq_protocol.md.

Whoever needs bytes (the board's reader thread while streaming, or a command
waiting for its reply) pumps the port under one lock: parsed data goes to a chunk
queue, replies to a reply queue.  So a command works the same whether or not a
stream is running, and nothing waits forever: every wait has a deadline.
"""

from __future__ import annotations

import contextlib
import errno
import os
import threading
import time
from collections import deque

import serial

from drivers.daq import RawChunk
from drivers.daq_protocol import (
    COMMAND_IDENTIFY,
    COMMAND_START,
    COMMAND_STOP,
    BoardConfiguration,
    BoardIdentity,
    FrameParser,
    IndexUnwrapper,
    ProtocolError,
    Reply,
    encode_command,
    encode_configure,
    parse_reply,
)
from drivers.interfaces import DeviceError, DeviceNotFoundError, WrongDeviceError

READ_POLL_S = 0.05  # the port's read timeout: the longest a read blocks before we look around


class SerialDaqBackend:
    """The DAQ board on a serial port; pass it to :class:`drivers.daq.DaqBoard`."""

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = 12_000_000,  # USB CDC ignores it; a UART bridge must match the board
        reply_timeout_s: float = 1.0,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.reply_timeout_s = reply_timeout_s
        self._serial: serial.Serial | None = None
        self._parser = FrameParser()
        self._pump_lock = threading.Lock()
        self._chunks: deque[RawChunk] = deque()
        self._replies: deque[str] = deque()
        self._indices = IndexUnwrapper()
        self._frames_rejected = 0
        self.bytes_discarded = 0
        self._gone = ""

    @property
    def description(self) -> str:
        return f"serial port {self.port}"

    @property
    def frames_rejected(self) -> int:
        return self._frames_rejected

    # --- connection -----------------------------------------------------------------------
    def connect(self) -> BoardIdentity:
        """Open the port, stop any stream left running, and ask who is there.

        On any failure the port is closed again.
        """
        if self._serial is None:
            self._open()
        try:
            self._command(encode_command(COMMAND_STOP), expect_reply=False)
            self._chunks.clear()
            reply = self._command(encode_command(COMMAND_IDENTIFY), wrong_device_on_silence=True)
            try:
                return BoardIdentity.from_reply(self._require_ok(reply, COMMAND_IDENTIFY))
            except ProtocolError as error:
                raise WrongDeviceError(
                    f"{self.description} answered IDN? with something that is not a DAQ board "
                    f"identity: {error}"
                ) from None
        except DeviceError:
            self.close()
            raise

    def _open(self) -> None:
        if not os.path.exists(self.port):
            raise DeviceNotFoundError(f"DAQ board port {self.port} does not exist")
        try:
            self._serial = serial.Serial(self.port, self.baudrate, timeout=READ_POLL_S)
        except (serial.SerialException, OSError) as error:
            raise DeviceNotFoundError(f"cannot open DAQ board port {self.port}: {error}") from None
        # a new connection: nothing of the previous one (a vanished port, half a frame) remains
        self._gone = ""
        self._parser = FrameParser()
        self._chunks.clear()
        self._replies.clear()
        self._serial.reset_input_buffer()

    def close(self) -> None:
        if self._serial is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                self._serial.close()
            self._serial = None

    # --- commands -------------------------------------------------------------------------
    def configure(self, sample_rate_hz: float, channels: tuple[int, ...]) -> BoardConfiguration:
        reply = self._command(encode_configure(sample_rate_hz, channels))
        try:
            return BoardConfiguration.from_reply(self._require_ok(reply, "CONF"))
        except ProtocolError as error:
            raise DeviceError(f"{self.description}: {error}") from None

    def start(self) -> None:
        self._chunks.clear()
        self._indices.reset()
        self._require_ok(self._command(encode_command(COMMAND_START)), COMMAND_START)

    def stop(self) -> None:
        self._require_ok(self._command(encode_command(COMMAND_STOP)), COMMAND_STOP)

    def _require_ok(self, reply: str | None, command: str) -> Reply:
        if reply is None:
            raise DeviceError(
                f"the DAQ board on {self.description} did not answer {command} "
                f"within {self.reply_timeout_s:g} s"
            )
        try:
            parsed = parse_reply(reply)
        except ProtocolError as error:
            raise DeviceError(f"{self.description}: {error}") from None
        if not parsed.ok:
            raise DeviceError(
                f"the DAQ board on {self.description} refused {command}: {parsed.text}"
            )
        return parsed

    def _command(
        self, line: bytes, *, expect_reply: bool = True, wrong_device_on_silence: bool = False
    ) -> str | None:
        """Send one command line and wait for its reply frame (None if none came in time)."""
        self._replies.clear()
        self._write(line)
        deadline = time.monotonic() + self.reply_timeout_s
        while time.monotonic() < deadline:
            if self._replies:
                return self._replies.popleft()
            if self._pump_lock.acquire(timeout=0.01):
                try:
                    if not self._replies:
                        self._pump()
                finally:
                    self._pump_lock.release()
            elif self._gone:
                break
        if self._replies:
            return self._replies.popleft()
        if expect_reply and self._gone:  # the port itself failed: not a matter of who answers
            raise DeviceError(self._gone)
        if wrong_device_on_silence:
            raise WrongDeviceError(
                f"nothing on {self.description} answered {line.decode().strip()} within "
                f"{self.reply_timeout_s:g} s in the DAQ protocol: is this the DAQ board?"
            )
        return None

    def _write(self, line: bytes) -> None:
        if self._serial is None:
            raise DeviceError(f"{self.description} is not open")
        try:
            self._serial.write(line)
        except (serial.SerialException, OSError) as error:
            raise DeviceError(self._disconnected(error)) from None

    # --- the stream -----------------------------------------------------------------------
    def read_chunk(self, timeout_s: float) -> RawChunk | None:
        deadline = time.monotonic() + timeout_s
        while not self._chunks:
            if self._gone:
                raise DeviceError(self._gone)
            if time.monotonic() >= deadline:
                return None
            if self._pump_lock.acquire(timeout=0.01):
                try:
                    self._pump()
                finally:
                    self._pump_lock.release()
        return self._chunks.popleft()

    def _pump(self) -> None:
        """Read what the port has (waiting at most READ_POLL_S for the first byte) and parse it."""
        port = self._serial
        if port is None or self._gone:
            return
        try:
            waiting = port.in_waiting
            data = port.read(waiting if waiting else 1)
            if data and not waiting:
                data += port.read(port.in_waiting)
        except (serial.SerialException, OSError) as error:
            self._gone = self._disconnected(error)
            return
        if not data:
            return
        result = self._parser.feed(data)
        self._frames_rejected += result.frames_rejected
        self.bytes_discarded += result.bytes_discarded
        for run in result.runs:
            first = self._indices.unwrap(run.first_index_wire, run.n_samples)
            if first is None:  # behind us: a stale or repeated frame
                self._frames_rejected += run.frames
                continue
            self._chunks.append(RawChunk(first, run.analog, run.digital))
        self._replies.extend(result.replies)

    def _disconnected(self, error: Exception) -> str:
        gone = isinstance(error, OSError) and error.errno in (errno.EIO, errno.ENXIO, errno.ENODEV)
        reason = "device disconnected" if gone or "disconnected" in str(error) else "I/O error"
        return f"the DAQ board on {self.description} went away ({reason}: {error})"
