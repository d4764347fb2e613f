"""In-process simulated backend of the shaker amplifier: the firmware's registers without a wire.

It implements :class:`drivers.shaker.RegisterBackend`, so ``ShakerAmplifier``
runs unchanged on it: the driver's tests run on it beside Modbus TCP.  Refusals
answer like the Modbus device would (CommandRefusedError with the exception code).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from drivers.interfaces import DeviceError
from drivers.shaker import CommandRefusedError
from hardware_sim.amplifier_firmware import AmplifierFirmware, RegisterAccessError


class SimShakerBackend:
    """Register access straight into an :class:`AmplifierFirmware` (a new one by default)."""

    def __init__(self, firmware: AmplifierFirmware | None = None) -> None:
        self.firmware = firmware or AmplifierFirmware()
        self.description = "simulated shaker amplifier (in-process)"
        self._open = False
        self.writes: list[tuple[int, tuple[int, ...]]] = []  # every write received, in order

    def open(self) -> None:
        self._open = True

    def close(self) -> None:
        self._open = False

    def read_input_registers(self, address: int, count: int) -> list[int]:
        return self._call(self.firmware.read_input, address, count)

    def read_holding_registers(self, address: int, count: int) -> list[int]:
        return self._call(self.firmware.read_holding, address, count)

    def write_registers(self, address: int, values: Sequence[int]) -> None:
        if self._open:
            self.writes.append((address, tuple(values)))
        self._call(self.firmware.write, address, list(values))

    def _call(self, operation: Callable[..., Any], *args: Any) -> Any:
        if not self._open:
            raise DeviceError(f"{self.description}: not open")
        try:
            return operation(*args)
        except RegisterAccessError as error:
            raise CommandRefusedError(
                f"{self.description} refused the request with exception 0x{error.code:02X}: "
                f"{error}",
                error.code,
            ) from None
