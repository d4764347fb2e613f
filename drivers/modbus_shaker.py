"""Modbus backends of the shaker amplifier (pymodbus sync client): TCP and RTU.

They move raw registers only; scaling, limits and safety are the device's
(:class:`drivers.shaker.ShakerAmplifier`).  Every pymodbus failure becomes a
DeviceError whose message says where, which request and what happened.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Sequence
from typing import Any

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from drivers.interfaces import DeviceError, DeviceNotFoundError
from drivers.shaker import CommandRefusedError

EXCEPTION_NAMES = {
    0x01: "illegal function",
    0x02: "illegal data address",
    0x03: "illegal data value",
    0x04: "slave device failure",
    0x05: "acknowledge",
    0x06: "slave device busy",
    0x0A: "gateway path unavailable",
    0x0B: "gateway target failed to respond",
}

# pymodbus logs each failed request itself; our DeviceError already says it all.
if logging.getLogger("pymodbus").level == logging.NOTSET:  # unless the application chose
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


class _ModbusBackend:
    """Shared request handling of the TCP and RTU backends."""

    description = "Modbus device"

    def __init__(
        self, client: ModbusTcpClient | ModbusSerialClient, device_id: int, timeout_s: float
    ) -> None:
        self._client = client
        self.device_id = device_id
        self.timeout_s = timeout_s

    def close(self) -> None:
        with contextlib.suppress(OSError):  # the peer may have reset it already
            self._client.close()

    def read_input_registers(self, address: int, count: int) -> list[int]:
        reply = self._request(
            f"FC4 read of {count} input register(s) at {address}",
            self._client.read_input_registers,
            address,
            count=count,
        )
        return self._registers(reply, count, address)

    def read_holding_registers(self, address: int, count: int) -> list[int]:
        reply = self._request(
            f"FC3 read of {count} holding register(s) at {address}",
            self._client.read_holding_registers,
            address,
            count=count,
        )
        return self._registers(reply, count, address)

    def _registers(self, reply: Any, count: int, address: int) -> list[int]:
        """The reply's registers, when there are as many as asked (a reply whose byte count
        says otherwise is garbled: its words cannot be trusted to be the ones asked for)."""
        registers = list(reply.registers)
        if len(registers) != count:
            raise DeviceError(
                f"{self.description}: a garbled reply to a read of {count} register(s) at "
                f"{address}: it holds {len(registers)}"
            )
        return registers

    def write_registers(self, address: int, values: Sequence[int]) -> None:
        self._request(
            f"FC16 write of {list(values)} at {address}",
            self._client.write_registers,
            address,
            list(values),
        )

    def _request(self, what: str, call: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        try:
            reply = call(*args, device_id=self.device_id, **kwargs)
        except ModbusIOException as error:
            raise DeviceError(
                f"{self.description}: no reply to {what} within {self.timeout_s} s ({error})"
            ) from None
        except (ConnectionException, OSError) as error:  # OSError: a reset, a broken pipe
            raise DeviceError(
                f"{self.description}: connection lost during {what} ({error})"
            ) from None
        except ModbusException as error:
            raise DeviceError(f"{self.description}: {what} failed ({error})") from None
        if reply.isError():
            code = int(getattr(reply, "exception_code", 0))
            raise CommandRefusedError(
                f"{self.description} answered exception 0x{code:02X} "
                f"({EXCEPTION_NAMES.get(code, 'unknown')}) to {what}",
                code,
            )
        return reply


class ModbusTcpBackend(_ModbusBackend):
    """The amplifier on Modbus TCP at ``host:port``."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 502,
        *,
        device_id: int = 1,
        timeout_s: float = 1.0,
        retries: int = 1,
    ) -> None:
        client = ModbusTcpClient(
            host,
            port=port,
            timeout=timeout_s,
            retries=retries,
            reconnect_delay=0,
        )
        super().__init__(client, device_id, timeout_s)
        self.description = f"shaker amplifier at Modbus TCP {host}:{port}"

    def open(self) -> None:
        try:
            ok = self._client.connect()
        except (OSError, ModbusException) as error:
            ok, reason = False, str(error)
        else:
            reason = "connection refused, host unknown or unreachable"
        if not ok:
            raise DeviceNotFoundError(
                f"{self.description}: cannot connect ({reason}); is the controller on and the "
                "address right?"
            )


class ModbusRtuBackend(_ModbusBackend):
    """The amplifier on Modbus RTU over the serial port ``port`` (e.g. /dev/ttyUSB0)."""

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = 19200,
        parity: str = "N",
        stopbits: int = 1,
        device_id: int = 1,
        timeout_s: float = 1.0,
        retries: int = 1,
    ) -> None:
        client = ModbusSerialClient(
            port,
            baudrate=baudrate,
            parity=parity,
            stopbits=stopbits,
            timeout=timeout_s,
            retries=retries,
            reconnect_delay=0,
        )
        super().__init__(client, device_id, timeout_s)
        self.port = port
        self.description = f"shaker amplifier at Modbus RTU {port} (id {device_id})"

    def open(self) -> None:
        if not os.path.exists(self.port):
            raise DeviceNotFoundError(f"{self.description}: serial port {self.port} does not exist")
        try:
            ok = self._client.connect()
        except (OSError, ModbusException) as error:
            ok, reason = False, str(error)
        else:
            reason = "the port could not be opened (in use, or no permission?)"
        if not ok:
            raise DeviceNotFoundError(f"{self.description}: {reason}")
