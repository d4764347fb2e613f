"""A bench for the shaker driver: the same amplifier firmware behind Modbus TCP or in-process."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from drivers.amplifier_registers import Holding
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import RegisterBackend, ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.shaker_response import ShakerDynamics, ShakerResponse
from harness.fuzz.modbus import LIMITS  # the test amplifier's limits, the fuzzing's too
from tests.shaker.sim_shaker_backend import SimShakerBackend

# Quick mechanics so that tests settle in a fraction of a second.
FAST = ShakerDynamics(frequency_slew_hz_s=200.0, amplitude_tau_s=0.01, frequency_tau_s=0.01)
# Settings every drive must refuse under LIMITS before anything is sent: (name, value).
OUT_OF_LIMITS = [
    ("amplitude_m", 0.0051),  # just above max_amplitude_m
    ("amplitude_m", -1e-6),
    ("amplitude_m", math.nan),
    ("amplitude_m", "1e-3"),
    ("frequency_hz", 40.001),
    ("frequency_hz", 0.2),  # below min_frequency_hz
    ("frequency_hz", math.inf),
    ("ramp_rate_m_s", 0.0),
    ("ramp_rate_m_s", 0.06),  # above max_ramp_rate_m_s
    ("ramp_rate_m_s", True),
]


@dataclass
class Bench:
    """One amplifier (firmware), how the driver reaches it, and what it received."""

    kind: str
    firmware: AmplifierFirmware
    backend: RegisterBackend
    emulator: AmplifierEmulator | None

    def shaker(self, **options: object) -> ShakerAmplifier:
        return ShakerAmplifier(self.backend, LIMITS, **options)  # type: ignore[arg-type]

    def setpoint_writes(self) -> list[tuple[int, tuple[int, ...]]]:
        """Writes that reached the device, the background heartbeat left out."""
        if self.emulator is not None:
            seen = [(r.address, r.values) for r in self.emulator.requests if r.is_write]
        else:
            seen = list(self.backend.writes)  # type: ignore[attr-defined]
        return [(address, values) for address, values in seen if address != Holding.HEARTBEAT]

    def forget_writes(self) -> None:
        if self.emulator is not None:
            self.emulator.clear_log()
        else:
            self.backend.writes.clear()  # type: ignore[attr-defined]


def make_firmware(**options: object) -> AmplifierFirmware:
    return AmplifierFirmware(ShakerResponse(FAST), **options)  # type: ignore[arg-type]


@pytest.fixture(params=["modbus_tcp", "in_process"])
def bench(request: pytest.FixtureRequest) -> Iterator[Bench]:
    firmware = make_firmware()
    if request.param == "modbus_tcp":
        emulator = AmplifierEmulator(firmware).start()
        backend = ModbusTcpBackend("127.0.0.1", emulator.port, timeout_s=0.3, retries=0)
        yield Bench("modbus_tcp", firmware, backend, emulator)
        emulator.stop()
    else:
        yield Bench("in_process", firmware, SimShakerBackend(firmware), None)


@pytest.fixture
def emulator() -> Iterator[AmplifierEmulator]:
    with AmplifierEmulator(make_firmware()) as running:
        yield running
