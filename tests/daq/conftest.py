"""Fixtures for the DAQ board tests: one board factory per backend, so stream tests run on all.

``pty``: the Python emulator on a real pseudo-terminal, opened by the serial driver by
path.  ``inprocess``: the in-process simulated backend.  Both run the Python firmware
model and the same fault injector.  ``firmware``: the C firmware core (firmware/core)
built for this machine with gcc and served on a pty by its host main, the serial driver
unchanged in front of it; its link faults are armed through :class:`FirmwareFaults`.
Tests that need faults take them from ``make_faults``, which gives each backend its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from drivers.daq import DaqBoard
from drivers.serial_daq import SerialDaqBackend
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.daq_faults import DaqFaults
from hardware_sim.sample_source import SampleSource
from harness.firmware_host import FirmwareBoard, FirmwareFaults, build_host_firmware
from tests.daq.sim_daq_backend import SimDaqBackend

BACKENDS = ("pty", "inprocess", "firmware")
PTY_BOARDS = ("emulator", "firmware")  # what answers on a pty: the Python emulator or the C core
EMULATED_BACKENDS = ("pty", "inprocess")  # sources other than the counter: Python only
# The firmware's FIFO in these tests: half the board's 64 KiB, so that the stall test's
# 0.3 s of silence at 240 kB/s surely overflows it (and still 50 ms at the fastest paced
# stream here, 600 kB/s, beside the pty's own buffer).
TEST_FIFO_BYTES = 32 * 1024

MakeBoard = Callable[..., DaqBoard]


@pytest.fixture(scope="session")
def firmware_binary(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The firmware core and its host main, compiled once per session (gcc is required)."""
    return build_host_firmware(tmp_path_factory.mktemp("firmware"))


@pytest.fixture(params=BACKENDS)
def backend_kind(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture
def make_faults(backend_kind: str) -> Callable[..., DaqFaults | FirmwareFaults]:
    """``make_faults(seed=0)``: the fault switches for a board of this backend."""

    def make(seed: int = 0) -> DaqFaults | FirmwareFaults:
        return FirmwareFaults(seed) if backend_kind == "firmware" else DaqFaults(seed)

    return make


@pytest.fixture
def make_board(backend_kind: str, request: pytest.FixtureRequest) -> Iterator[MakeBoard]:
    """``make_board(source, faults=..., speed=..., sample_rate_hz=..., analog_channels=...)``."""
    boards: list[DaqBoard] = []
    devices: list[DaqEmulator | FirmwareBoard] = []

    def make(
        source: SampleSource,
        *,
        faults: DaqFaults | FirmwareFaults | None = None,
        speed: float = 5.0,
        sample_rate_hz: float = 20_000.0,
        analog_channels: tuple[int, ...] = (0, 1),
        role_buffer_s: float = 10.0,
        **emulator_options: object,
    ) -> DaqBoard:
        if backend_kind == "firmware":
            if faults is not None and not isinstance(faults, FirmwareFaults):
                raise TypeError("the firmware board takes its faults from make_faults")
            emulator_options.setdefault("fifo_bytes", TEST_FIFO_BYTES)
            device = FirmwareBoard(
                request.getfixturevalue("firmware_binary"),
                source=source,  # type: ignore[arg-type]
                speed=speed,
                faults=faults if faults is not None else FirmwareFaults(seed=1),
                **emulator_options,  # type: ignore[arg-type]
            ).start()
            devices.append(device)
            backend = SerialDaqBackend(device.port)
        elif backend_kind == "pty":
            faults = faults if faults is not None else DaqFaults(seed=1)
            emulator = DaqEmulator(source, speed=speed, faults=faults, **emulator_options).start()
            devices.append(emulator)
            backend = SerialDaqBackend(emulator.port)
        else:
            faults = faults if faults is not None else DaqFaults(seed=1)
            backend = SimDaqBackend(source, speed=speed, faults=faults, **emulator_options)
        board = DaqBoard(
            backend,
            sample_rate_hz=sample_rate_hz,
            analog_channels=analog_channels,
            stall_timeout_s=0.3,
            role_buffer_s=role_buffer_s,
            # As fast as possible: the consumer sets the pace, a full queue waits.
            when_role_full="wait" if math.isinf(speed) else "drop",
        )
        boards.append(board)
        return board

    yield make
    for board in boards:
        board.close()
    for device in devices:
        device.close()


@pytest.fixture(params=PTY_BOARDS)
def pty_board_kind(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture
def make_pty_board(
    pty_board_kind: str, request: pytest.FixtureRequest
) -> Iterator[Callable[..., DaqEmulator | FirmwareBoard]]:
    """``make_pty_board(source, speed=..., fifo_bytes=...)``: a started board on a pty, the
    Python emulator or the firmware core; either has ``port``, ``faults`` and ``close()``."""
    devices: list[DaqEmulator | FirmwareBoard] = []

    def make(source: SampleSource, **options: object) -> DaqEmulator | FirmwareBoard:
        if pty_board_kind == "firmware":
            device: DaqEmulator | FirmwareBoard = FirmwareBoard(
                request.getfixturevalue("firmware_binary"),
                source=source,  # type: ignore[arg-type]
                **options,  # type: ignore[arg-type]
            )
        else:
            device = DaqEmulator(source, **options)  # type: ignore[arg-type]
        devices.append(device.start())
        return device

    yield make
    for device in devices:
        device.close()
