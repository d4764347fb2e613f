"""The C firmware core (firmware/core) built for this machine and served on a pty by its host
main (firmware/host/host_main.c): the board the serial driver talks to, as it would a
flashed board on /dev/ttyACM0.

:func:`build_host_firmware` compiles it with gcc (no gcc: a loud error, never a skip);
:class:`FirmwareBoard` runs it; :class:`FirmwareFaults` arms its link faults over the
process's stdin and reads back what they cost, with the methods of
:class:`hardware_sim.daq_faults.DaqFaults`, so a test checks both boards the same way.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import subprocess
import threading
import time
from dataclasses import replace
from pathlib import Path

from drivers.daq_protocol import BoardIdentity
from hardware_sim.daq_faults import OVERFLOW, FaultRecord, samples_lost
from hardware_sim.daq_firmware import DEFAULT_IDENTITY
from hardware_sim.sample_source import CounterSource

FIRMWARE_DIR = Path(__file__).resolve().parents[1] / "firmware"
C_FLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra", "-Werror")
# The host build's own identity: the board's, with the serial number of the host build.
HOST_IDENTITY = replace(DEFAULT_IDENTITY, serial="HOST0001")


class FirmwareBuildError(RuntimeError):
    """The firmware core could not be built for this machine."""


def host_sources() -> list[Path]:
    """The portable core and the host main: every C file the host binary is made of."""
    return sorted((FIRMWARE_DIR / "core").glob("*.c")) + sorted((FIRMWARE_DIR / "host").glob("*.c"))


def build_host_firmware(out_dir: Path) -> Path:
    """Compile the core and the host main with gcc into ``out_dir``; the binary's path."""
    gcc = shutil.which("gcc")
    if gcc is None:
        raise FirmwareBuildError(
            "gcc is not on PATH: the firmware core cannot be built for the host. Install gcc "
            "(Debian: apt-get install gcc); the DAQ tests need it and CI has it."
        )
    binary = Path(out_dir) / "irdaq-host"
    command = [gcc, *C_FLAGS, "-o", str(binary), *map(str, host_sources()), "-lm"]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise FirmwareBuildError(f"{' '.join(command)} failed:\n{done.stderr}")
    return binary


class FirmwareFaults:
    """Link faults of a :class:`FirmwareBoard`, armed at run time, and the log of their cost.

    One-shot faults hit the next data frames sent, periodic ones every n-th frame until
    ``clear()``, as with :class:`~hardware_sim.daq_faults.DaqFaults`.  The garbage is
    random bytes of the length given.  A stall stops the link, not the sample clock: the
    board's FIFO fills and the frames that find no room are skipped, logged as
    ``overflow``.  Reading ``log`` first waits until the board has reported everything
    that happened before the read.
    """

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self._board: FirmwareBoard | None = None
        self._lock = threading.Lock()
        self._log: list[FaultRecord] = []
        self._synced: set[str] = set()
        self._changed = threading.Condition(self._lock)
        self._sync_count = 0
        self._unplugged = False
        self._stall_timer: threading.Timer | None = None

    # --- wiring to the process ------------------------------------------------------------
    def attach(self, board: FirmwareBoard) -> None:
        if self._board is not None:
            raise RuntimeError("these faults already belong to a running board")
        self._board = board

    def _send(self, line: str) -> None:
        if self._board is None:
            raise RuntimeError("arm the faults after the board is made (make_board)")
        self._board.control(line)

    def _reported(self, line: str) -> None:
        """A line of the board's stdout: a fault report or a sync answer."""
        words = line.split()
        with self._changed:
            if words[:1] == ["fault"] and len(words) == 5:
                kind, first, n, n_bytes = words[1], int(words[2]), int(words[3]), int(words[4])
                last = self._log[-1] if self._log else None
                if (
                    kind == OVERFLOW
                    and last is not None
                    and last.kind == kind
                    and last.first_index + last.n_samples == first
                ):
                    self._log[-1] = FaultRecord(kind, last.first_index, last.n_samples + n)
                else:
                    self._log.append(FaultRecord(kind, first, n, n_bytes))
            elif words[:1] == ["synced"] and len(words) == 2:
                self._synced.add(words[1])
            self._changed.notify_all()

    # --- switching faults on and off --------------------------------------------------------
    def inject_garbage(self, garbage: int, *, every: int = 0) -> None:
        """Random garbage of ``garbage`` bytes before the next frame (or every n-th frame)."""
        if not isinstance(garbage, int):
            raise TypeError("the firmware's link injects random bytes: give their number")
        self._send(f"garbage_every {garbage} {every}" if every else f"garbage {garbage}")

    def drop_bytes(self, n_bytes: int = 7, *, frames: int = 1) -> None:
        if n_bytes < 1:
            raise ValueError(f"n_bytes={n_bytes} must be at least 1")
        self._send(f"drop {n_bytes} {frames}")

    def corrupt_crc(self, *, frames: int = 1, every: int = 0) -> None:
        self._send(f"corrupt_every {every}" if every else f"corrupt {frames}")

    def stall(self, seconds: float = math.inf) -> None:
        self._send("stall")
        if math.isfinite(seconds):
            self._stall_timer = threading.Timer(seconds, self.resume)
            self._stall_timer.daemon = True
            self._stall_timer.start()

    def resume(self) -> None:
        self._send("resume")

    def unplug(self) -> None:
        self._unplugged = True
        self._send("unplug")

    def clear(self) -> None:
        self._send("clear")

    @property
    def unplugged(self) -> bool:
        return self._unplugged

    # --- the truth, for tests ------------------------------------------------------------------
    @property
    def log(self) -> list[FaultRecord]:
        if self._board is not None and self._board.running:
            with self._lock:
                self._sync_count += 1
                token = str(self._sync_count)
            self._send(f"sync {token}")
            deadline = time.monotonic() + 5
            with self._changed:
                while token not in self._synced:
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or not self._board.running:
                        break
                    self._changed.wait(min(remaining, 0.1))
        with self._lock:
            return list(self._log)

    def samples_lost(self, before_index: int | None = None) -> int:
        """Samples the faults cost among indices below ``before_index`` (all when None)."""
        return samples_lost(self.log, before_index)


class FirmwareBoard:
    """The host build of the firmware in its own process; ``port`` is its pty's slave path.

    ``speed`` scales its sample clock (math.inf: as fast as the link takes frames); the
    counter source's tach settings, the identity's model, serial and rate limits, and the
    FIFO size are passed on its command line.
    """

    def __init__(
        self,
        binary: Path,
        *,
        source: CounterSource | None = None,
        speed: float = 1.0,
        faults: FirmwareFaults | None = None,
        identity: BoardIdentity = HOST_IDENTITY,
        fifo_bytes: int = 64 * 1024,
        max_samples_per_frame: int = 256,
    ) -> None:
        source = source if source is not None else CounterSource()
        if not isinstance(source, CounterSource):
            raise TypeError(
                f"the firmware's host build samples a counter, not a {type(source).__name__}"
            )
        fixed = (identity.channels, identity.adc_bits, identity.range_v, identity.firmware)
        if fixed != (4, 16, 10.0, HOST_IDENTITY.firmware):
            raise ValueError(f"the firmware's channels, ADC and version are its own: {identity}")
        self.faults = faults if faults is not None else FirmwareFaults()
        self.arguments = [
            str(binary),
            "--speed", "inf" if math.isinf(speed) else repr(float(speed)),
            "--fifo-bytes", str(fifo_bytes),
            "--samples-per-frame", str(max_samples_per_frame),
            "--tach-period", str(source.tach_period),
            "--tach-width", str(source.tach_width),
            "--tach-phase", str(source.tach_phase),
            "--seed", str(self.faults.seed),
            "--model", identity.model,
            "--serial", identity.serial,
            "--min-rate-hz", repr(identity.min_rate_hz),
            "--max-rate-hz", repr(identity.max_rate_hz),
        ]  # fmt: skip
        self.port = ""
        self._process: subprocess.Popen[str] | None = None
        self._reader: threading.Thread | None = None
        self._write_lock = threading.Lock()

    def start(self) -> FirmwareBoard:
        """Start the process and wait for its port (once; again: no-op)."""
        if self._process is not None:
            return self
        self._process = subprocess.Popen(
            self.arguments, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1
        )
        assert self._process.stdout is not None
        self.port = self._process.stdout.readline().strip()
        if not self.port.startswith("/dev/"):
            self.close()
            raise RuntimeError(f"the firmware's host build printed no port (got {self.port!r})")
        self.faults.attach(self)
        self._reader = threading.Thread(target=self._read_reports, daemon=True)
        self._reader.start()
        return self

    def _read_reports(self) -> None:
        assert self._process is not None and self._process.stdout is not None
        for line in self._process.stdout:
            self.faults._reported(line)

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def control(self, line: str) -> None:
        """One control line to the process (see firmware/host/host_main.c)."""
        assert self._process is not None and self._process.stdin is not None
        with self._write_lock:
            self._process.stdin.write(line + "\n")
            self._process.stdin.flush()

    def close(self) -> None:
        """Close its stdin (it closes the pty and exits) and reap it."""
        process = self._process
        if process is None:
            return
        if process.stdin is not None and not process.stdin.closed:
            with self._write_lock, contextlib.suppress(BrokenPipeError):
                process.stdin.close()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        if self._reader is not None:
            self._reader.join(timeout=5)

    def __enter__(self) -> FirmwareBoard:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
