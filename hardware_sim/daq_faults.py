"""Switchable faults of the simulated DAQ board, and the log of exactly what they damaged.

One :class:`DaqFaults` object drives both simulated backends: the pty emulator
applies it to the bytes of each frame (garbage between frames, bytes dropped
mid-frame, a corrupted CRC), the tests' in-process backend to whole chunks (a damaged
frame is a lost chunk).  Stalls and unplugging act on the link.  Every fault that
costs samples is logged with the exact running indices it cost, so a test can
demand that the driver's lost-sample count is exact.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

GARBAGE = "garbage"  # bytes between frames: costs no sample
DROPPED_BYTES = "dropped_bytes"  # bytes removed mid-frame: the frame is lost
CORRUPT_CRC = "corrupt_crc"  # the CRC field flipped: the frame is lost
STALL = "stall"  # the link sent nothing; samples acquired meanwhile are lost
OVERFLOW = "overflow"  # the board's FIFO was full (host not reading): the frame is lost
UNPLUG = "unplug"  # the device went away


@dataclass(frozen=True)
class FaultRecord:
    """One fault as it happened: samples ``[first_index, first_index + n_samples)`` lost."""

    kind: str
    first_index: int
    n_samples: int
    n_bytes: int = 0


@dataclass(frozen=True)
class FrameFate:
    """What happens to one outgoing data frame."""

    garbage_before: bytes = b""
    damage: str | None = None  # DROPPED_BYTES, CORRUPT_CRC, or None when sent intact
    drop_bytes: int = 0


class DaqFaults:
    """Faults armed at run time (thread-safe) and the log of their effects.

    One-shot faults (``inject_garbage``, ``drop_bytes``, ``corrupt_crc``) hit the next
    frames sent; periodic ones (``*_every`` arguments) keep hitting every n-th frame
    until switched off with ``clear()``.
    """

    def __init__(self, seed: int = 0) -> None:
        self._lock = threading.Lock()
        self._rng = np.random.default_rng(seed)
        self._garbage: list[bytes] = []
        self._drop: list[int] = []
        self._corrupt = 0
        self._garbage_every = 0
        self._garbage_length = 0
        self._corrupt_every = 0
        self._frames_seen = 0
        self._stall_until = 0.0
        self._unplugged = threading.Event()
        self._log: list[FaultRecord] = []

    # --- switching faults on and off -------------------------------------------------
    def inject_garbage(self, garbage: bytes | int, *, every: int = 0) -> None:
        """Garbage before the next frame (bytes given, or that many random bytes).

        With ``every=n`` random garbage of that length goes before every n-th frame.
        """
        if every and not isinstance(garbage, int):
            raise ValueError("inject_garbage(every=n) takes a length in bytes, not the bytes")
        with self._lock:
            if every:
                self._garbage_every, self._garbage_length = every, garbage
            elif isinstance(garbage, int):
                self._garbage.append(self._random_bytes(garbage))
            else:
                self._garbage.append(bytes(garbage))

    def drop_bytes(self, n_bytes: int = 7, *, frames: int = 1) -> None:
        """Remove ``n_bytes`` from the middle of each of the next ``frames`` frames."""
        if n_bytes < 1:
            raise ValueError(f"n_bytes={n_bytes} must be at least 1")
        with self._lock:
            self._drop.extend([n_bytes] * frames)

    def corrupt_crc(self, *, frames: int = 1, every: int = 0) -> None:
        """Flip the CRC of the next ``frames`` frames, or of every n-th frame from now."""
        with self._lock:
            if every:
                self._corrupt_every = every
            else:
                self._corrupt += frames

    def stall(self, seconds: float = math.inf) -> None:
        """The board stops sending for ``seconds`` (wall time); its sample clock runs on."""
        with self._lock:
            self._stall_until = time.monotonic() + seconds

    def resume(self) -> None:
        """End a stall now."""
        with self._lock:
            self._stall_until = 0.0

    def unplug(self) -> None:
        """The device disappears; the backend closes its end of the link."""
        self._unplugged.set()

    def clear(self) -> None:
        """Switch every armed or periodic fault off (the log stays)."""
        with self._lock:
            self._garbage.clear()
            self._drop.clear()
            self._corrupt = self._garbage_every = self._corrupt_every = 0
            self._stall_until = 0.0

    # --- state the backends consult ---------------------------------------------------
    @property
    def unplugged(self) -> bool:
        """True once ``unplug()`` was called: the device is gone for good."""
        return self._unplugged.is_set()

    @property
    def stalled(self) -> bool:
        """True while a stall lasts: the board sends nothing."""
        return time.monotonic() < self._stall_until

    def frame_fate(self, first_index: int, n_samples: int, frame_bytes: int) -> FrameFate:
        """Decide (and log) what happens to the next data frame."""
        with self._lock:
            self._frames_seen += 1
            garbage = self._garbage.pop(0) if self._garbage else b""
            if self._garbage_every and self._frames_seen % self._garbage_every == 0:
                garbage += self._random_bytes(self._garbage_length)
            if garbage:
                self._log.append(FaultRecord(GARBAGE, first_index, 0, len(garbage)))
            damage, dropped = None, 0
            if self._drop:
                damage, dropped = DROPPED_BYTES, min(self._drop.pop(0), frame_bytes // 2)
            elif self._corrupt or (
                self._corrupt_every and self._frames_seen % self._corrupt_every == 0
            ):
                self._corrupt = max(0, self._corrupt - 1)
                damage = CORRUPT_CRC
            if damage is not None:
                self._log.append(FaultRecord(damage, first_index, n_samples, dropped))
            return FrameFate(garbage, damage, dropped)

    def damage_position(self, frame_bytes: int, n_bytes: int) -> int:
        """Where mid-frame bytes are dropped: somewhere after the header, before the CRC."""
        with self._lock:
            return int(self._rng.integers(12, max(13, frame_bytes - 4 - n_bytes)))

    def record(self, kind: str, first_index: int, n_samples: int) -> None:
        """Log samples lost by the link itself (stall, FIFO overflow)."""
        with self._lock:
            last = self._log[-1] if self._log else None
            if last and last.kind == kind and last.first_index + last.n_samples == first_index:
                self._log[-1] = FaultRecord(kind, last.first_index, last.n_samples + n_samples)
            else:
                self._log.append(FaultRecord(kind, first_index, n_samples))

    # --- the truth, for tests -----------------------------------------------------------
    @property
    def log(self) -> list[FaultRecord]:
        with self._lock:
            return list(self._log)

    def samples_lost(self, before_index: int | None = None) -> int:
        """Samples the faults cost among indices below ``before_index`` (all when None)."""
        return samples_lost(self.log, before_index)

    def _random_bytes(self, n: int) -> bytes:
        return self._rng.integers(0, 256, size=n, dtype=np.uint8).tobytes()


def samples_lost(log: Iterable[FaultRecord], before_index: int | None = None) -> int:
    """Samples the faults of ``log`` cost among indices below ``before_index`` (all when
    None)."""
    total = 0
    for record in log:
        if before_index is None:
            total += record.n_samples
        else:
            end = record.first_index + record.n_samples
            total += max(0, min(end, before_index) - record.first_index)
    return total
