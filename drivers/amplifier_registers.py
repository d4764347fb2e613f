"""The shaker amplifier's Modbus register map (docs/amplifier_registers.md): driver and emulator.

Addresses are 0-based protocol addresses (the "PDU address"; some vendor tools show
them +1 or +30001/+40001).  Every value is an unsigned 16-bit register; a 32-bit
value occupies two consecutive registers, high word first (big-endian word order),
and must be written in one "write multiple registers" (FC16) request.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag

MODEL_CODE = 0x5348  # "SH": the impact-rig shaker amplifier
MAP_VERSION = 1

# Hardware range of the amplifier itself: writes beyond these get exception 0x03.
DEVICE_MAX_FREQUENCY_MHZ = 200_000  # 200 Hz
DEVICE_MAX_AMPLITUDE_UM = 50_000  # 50 mm, half the laser's 100 mm range
DEVICE_MAX_RAMP_RATE_UM_S = 50_000
WATCHDOG_MIN_MS = 50
WATCHDOG_MAX_MS = 60_000
WATCHDOG_DEFAULT_MS = 1_000
DEFAULT_RAMP_RATE_UM_S = 5_000


class Holding(IntEnum):
    """Holding registers (read FC3, write FC6 single or FC16 multiple)."""

    FREQUENCY_MHZ_HI = 0  # drive frequency setpoint, mHz, uint32 high word
    FREQUENCY_MHZ_LO = 1  # low word
    AMPLITUDE_UM = 2  # drive amplitude setpoint (table displacement amplitude), micrometres
    RAMP_RATE_UM_S = 3  # amplitude slew limit, micrometres per second (> 0)
    ENABLE = 4  # 1 = drive on, 0 = ramp to zero; refused (0x03) while a fault is latched
    HEARTBEAT = 5  # host writes any value at least once per watchdog timeout
    COMMAND = 6  # write 1 = clear latched faults; reads 0
    WATCHDOG_MS = 7  # watchdog timeout, milliseconds


HOLDING_COUNT = 8


class Input(IntEnum):
    """Input registers (read FC4), read-only."""

    MODEL_CODE = 0  # 0x5348
    FIRMWARE = 1  # major << 8 | minor
    MAP_VERSION = 2  # 1
    STATUS = 3  # Status bits
    FAULTS = 4  # Fault bits (latched)
    MEASURED_FREQUENCY_MHZ_HI = 5  # measured drive frequency, mHz, uint32 high word
    MEASURED_FREQUENCY_MHZ_LO = 6
    MEASURED_AMPLITUDE_UM = 7  # measured table amplitude, micrometres
    HEARTBEAT_ECHO = 8  # last heartbeat value received


INPUT_COUNT = 9


class Command(IntEnum):
    """Values of the COMMAND register."""

    NONE = 0
    CLEAR_FAULTS = 1


class Status(IntFlag):
    """Bits of the STATUS input register."""

    ENABLED = 0x0001  # drive output on
    RAMPING = 0x0002  # amplitude or frequency still moving toward the setpoint
    AT_ZERO = 0x0004  # MEASURED_AMPLITUDE_UM reads 0 (below half a micrometre)
    FAULTED = 0x0008  # at least one fault latched


class Fault(IntFlag):
    """Bits of the FAULTS input register; latched until CLEAR_FAULTS (and the cause gone)."""

    OVER_AMPLITUDE = 0x0001
    OVER_CURRENT = 0x0002
    OVER_TEMPERATURE = 0x0004
    WATCHDOG_EXPIRED = 0x0008
    INTERLOCK_OPEN = 0x0010


FAULT_WORDS: dict[Fault, str] = {
    Fault.OVER_AMPLITUDE: "over-amplitude",
    Fault.OVER_CURRENT: "over-current",
    Fault.OVER_TEMPERATURE: "over-temperature",
    Fault.WATCHDOG_EXPIRED: "watchdog expired",
    Fault.INTERLOCK_OPEN: "interlock open",
}


def fault_words(bits: int) -> tuple[str, ...]:
    """Plain-word names of the fault bits set in ``bits`` (unknown bits named by number)."""
    words = [word for flag, word in FAULT_WORDS.items() if bits & flag]
    known = 0
    for flag in FAULT_WORDS:
        known |= int(flag)
    unknown = bits & ~known & 0xFFFF
    words += [f"fault bit {i}" for i in range(16) if unknown & (1 << i)]
    return tuple(words)


def split_u32(value: int) -> list[int]:
    """A uint32 as two registers, high word first."""
    if not 0 <= value <= 0xFFFF_FFFF:
        raise ValueError(f"{value} does not fit in an unsigned 32-bit register pair")
    return [(value >> 16) & 0xFFFF, value & 0xFFFF]


def join_u32(high: int, low: int) -> int:
    """Two registers (high word first) as one uint32."""
    return ((high & 0xFFFF) << 16) | (low & 0xFFFF)
