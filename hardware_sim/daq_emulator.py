"""The DAQ board emulated on a pseudo-terminal: the driver opens its port like /dev/ttyACM0.

The emulator owns the pty master; the slave's path (``emulator.port``) is what a
driver opens.  It answers the ASCII commands of docs/daq_protocol.md with reply
frames and, while streaming, sends data frames paced by the board's sample clock
(real time, ``speed`` times faster, or as fast as the host reads; by default the
source's own ``speed_factor`` if it has one, else real time).  Faults from
:mod:`hardware_sim.daq_faults` are applied to the bytes on the way out.

Run stand-alone (prints the port, serves until interrupted)::

    python -m hardware_sim.daq_emulator --speed 1
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import select
import sys
import threading
import tty
from dataclasses import replace

from drivers.daq_protocol import (
    MAX_COMMAND_BYTES,
    BoardIdentity,
    encode_data_frame,
    encode_reply_frame,
)
from hardware_sim.daq_faults import (
    CORRUPT_CRC,
    DROPPED_BYTES,
    OVERFLOW,
    STALL,
    UNPLUG,
    DaqFaults,
)
from hardware_sim.daq_firmware import DEFAULT_IDENTITY, DaqFirmware
from hardware_sim.sample_source import CounterSource, SampleSource

# Frames produced per pass of the service loop before what is queued is written: a board
# whose simulation falls behind its clock (a loaded PC) streams on a few frames at a time
# instead of computing everything due first (seconds to minutes of silence, then lost
# frames from a full FIFO)
FRAMES_PER_PASS = 8


class DaqEmulator:
    """A simulated DAQ board behind a pty; start() it, point a driver at ``port``."""

    def __init__(
        self,
        source: SampleSource,
        *,
        identity: BoardIdentity = DEFAULT_IDENTITY,
        speed: float | None = None,
        faults: DaqFaults | None = None,
        fifo_bytes: int = 512 * 1024,
        max_samples_per_frame: int = 256,
        wiring: dict[int, str] | None = None,
    ) -> None:
        self.firmware = DaqFirmware(
            source,
            identity=identity,
            wiring=wiring,
            max_samples_per_frame=max_samples_per_frame,
            speed=speed,
        )
        self.faults = faults if faults is not None else DaqFaults()
        self.fifo_bytes = fifo_bytes
        self._master = -1
        self._slave = -1
        self.port = ""
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._out = bytearray()
        self._commands = bytearray()
        self.frames_sent = 0

    # --- life cycle ------------------------------------------------------------------
    def start(self) -> DaqEmulator:
        """Open the pty pair and serve it from a background thread (once; again: no-op)."""
        if self._thread is not None:
            return self
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line editing: bytes pass untouched
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self._running.set()
        self._thread = threading.Thread(target=self._serve, name="daq-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and close the pty (the driver sees the device disappear)."""
        self._running.clear()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5)
        if thread is None or not thread.is_alive():
            self._close_fds()  # else the serving thread closes them as it ends: never under it

    @property
    def serving(self) -> bool:
        """True from start() until close(), an unplug fault or an I/O error ends the service."""
        return self._running.is_set()

    def __enter__(self) -> DaqEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    # --- the serving loop ------------------------------------------------------------
    def _serve(self) -> None:
        try:
            while self._running.is_set():
                if self.faults.unplugged:
                    self.faults.record(UNPLUG, self.firmware.next_index, 0)
                    return
                wait = self._time_to_next_frame()
                writable = [self._master] if self._out else []
                readable, can_write, _ = select.select([self._master], writable, [], wait)
                if readable:
                    self._read_commands()
                if self.firmware.streaming:
                    self._produce_due_frames()
                if self._out and (can_write or not writable):
                    self._write_some()
        except OSError as error:
            if self._running.is_set():
                print(f"daq emulator on {self.port} stopped: {error}", file=sys.stderr)
        finally:
            # however the service ends, the device is gone: the driver sees the pty close
            self._running.clear()
            self._close_fds()

    def _time_to_next_frame(self) -> float:
        if not self.firmware.streaming:
            return 0.05
        if not self.firmware.paced:
            return 0.0 if len(self._out) < self.fifo_bytes else 0.05
        return min(0.05, self.firmware.seconds_to_next_frame())

    def _read_commands(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except BlockingIOError:
            return
        except OSError as error:
            if error.errno == errno.EIO:  # nobody holds the slave open: nothing to read
                return
            raise
        self._commands += data
        while b"\n" in self._commands:
            line, _, rest = self._commands.partition(b"\n")
            self._commands = bytearray(rest)
            text = line.decode("ascii", errors="replace").strip("\r ")
            self._out += encode_reply_frame(self.firmware.handle(text))
        if len(self._commands) > MAX_COMMAND_BYTES:  # a line that never ends is noise
            self._out += encode_reply_frame("ERR command line too long")
            self._commands.clear()

    def _produce_due_frames(self) -> None:
        config = self.firmware.configuration
        per_frame = config.samples_per_frame
        paced = self.firmware.paced
        if paced:
            due_frames = min(self.firmware.frames_due(), FRAMES_PER_PASS)
        else:
            due_frames = 1 if len(self._out) < self.fifo_bytes else 0
        for _ in range(due_frames):
            first = self.firmware.next_index
            if self.faults.stalled and paced:
                self.firmware.skip(per_frame)
                self.faults.record(STALL, first, per_frame)
                continue
            if self.faults.stalled:  # as fast as possible: the clock waits with the link
                return
            if len(self._out) >= self.fifo_bytes:
                self.firmware.skip(per_frame)
                self.faults.record(OVERFLOW, first, per_frame)
                continue
            chunk = self.firmware.acquire()
            frame = encode_data_frame(first, config.channels, chunk.analog, chunk.digital)
            fate = self.faults.frame_fate(first, per_frame, len(frame))
            if fate.damage == CORRUPT_CRC:
                frame = frame[:-1] + bytes([frame[-1] ^ 0xFF])
            elif fate.damage == DROPPED_BYTES:
                at = self.faults.damage_position(len(frame), fate.drop_bytes)
                frame = frame[:at] + frame[at + fate.drop_bytes :]
            self._out += fate.garbage_before
            self._out += frame
            self.frames_sent += 1

    def _write_some(self) -> None:
        try:
            written = os.write(self._master, self._out[: 1 << 16])
        except BlockingIOError:
            return
        del self._out[:written]


def _main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hardware_sim.daq_emulator",
        description="Emulate the IRDAQ-4 board on a pseudo-terminal fed by a counter source; "
        "prints the port path on the first line, then serves until interrupted.",
    )
    parser.add_argument("--speed", type=float, default=1.0, help="clock speed factor (inf: ASAP)")
    parser.add_argument("--samples-per-frame", type=int, default=256)
    parser.add_argument("--fifo-bytes", type=int, default=512 * 1024)
    parser.add_argument(
        "--max-rate-hz",
        type=float,
        default=DEFAULT_IDENTITY.max_rate_hz,
        help="the board's top sample rate (raise it to measure a host's headroom)",
    )
    args = parser.parse_args(argv)
    emulator = DaqEmulator(
        CounterSource(),
        identity=replace(DEFAULT_IDENTITY, max_rate_hz=args.max_rate_hz),
        speed=args.speed,
        fifo_bytes=args.fifo_bytes,
        max_samples_per_frame=args.samples_per_frame,
    ).start()
    print(emulator.port, flush=True)
    try:
        while emulator.serving:
            line = sys.stdin.readline()
            if not line:  # parent went away
                break
            if line.strip() == "log":
                lost = emulator.faults.samples_lost()
                print(f"frames_sent={emulator.frames_sent} samples_lost={lost}", flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        emulator.close()
    return 0


if __name__ == "__main__":
    sys.exit(_main())
