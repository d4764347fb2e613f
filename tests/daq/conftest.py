"""Fixtures for the DAQ board tests: one board factory per backend, so stream tests run on both.

``pty``: the emulated board on a real pseudo-terminal, opened by the serial driver
by path.  ``inprocess``: the in-process simulated backend.  Both run the same
firmware model and the same fault injector.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import pytest

from drivers.daq import DaqBoard
from drivers.serial_daq import SerialDaqBackend
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.daq_faults import DaqFaults
from hardware_sim.sample_source import SampleSource
from tests.daq.sim_daq_backend import SimDaqBackend

BACKENDS = ("pty", "inprocess")

MakeBoard = Callable[..., DaqBoard]


@pytest.fixture(params=BACKENDS)
def backend_kind(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture
def make_board(backend_kind: str) -> Iterator[MakeBoard]:
    """``make_board(source, faults=..., speed=..., sample_rate_hz=..., analog_channels=...)``."""
    boards: list[DaqBoard] = []
    emulators: list[DaqEmulator] = []

    def make(
        source: SampleSource,
        *,
        faults: DaqFaults | None = None,
        speed: float = 5.0,
        sample_rate_hz: float = 20_000.0,
        analog_channels: tuple[int, ...] = (0, 1),
        role_buffer_s: float = 10.0,
        **emulator_options: object,
    ) -> DaqBoard:
        faults = faults if faults is not None else DaqFaults(seed=1)
        if backend_kind == "pty":
            emulator = DaqEmulator(source, speed=speed, faults=faults, **emulator_options).start()
            emulators.append(emulator)
            backend = SerialDaqBackend(emulator.port)
        else:
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
    for emulator in emulators:
        emulator.close()
