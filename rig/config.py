"""The rig configuration file (TOML): devices and ports, calibrations, safety limits, rig constants.

Parsed with tomllib into frozen dataclasses; every value is checked at load time and
an error names the file, the key and what was expected.  The shipped default
(``rig/default_rig.toml``) runs the virtual rig.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

from analysis import quantities as q
from analysis.packed import ParameterError
from drivers.limits import LimitsConfigError, ShakerLimits
from drivers.sensors import LaserCalibration, PotentiometerCalibration, TachometerCalibration

DEFAULT_CONFIG_NAME = "default_rig.toml"
RIG_KINDS = ("virtual", "real")
SHAKER_TRANSPORTS = ("tcp", "rtu")
SHAKER_KINDS = ("modbus", "scpi")  # the amplifier's Modbus controller, or a SCPI function generator
SCPI_GAIN_M_PER_V_RANGE = (1e-7, 1.0)  # table amplitude per volt of generator amplitude
SCPI_MAX_VPP = 40.0  # no bench generator goes beyond (20 Vpp into high-Z is typical)
MAX_INPUT_V = 100.0  # no DAQ input reads beyond this
GAIN_RAD_PER_V_RANGE = (1e-6, 100.0)
M_PER_UNIT_RANGE = (1e-12, 1.0)  # from a count of a 32-bit converter to a volt of a 1 m sensor
MAX_TABLE_ZERO_M = 1.0


class ConfigError(ValueError):
    """A rig file that cannot be used; the message names the file, the key and what was expected."""


@dataclass(frozen=True)
class RigConstants:
    """docs/MODEL.md section 3 constants of this rig."""

    m_kg: float
    l_m: float
    L_m: float
    R_m: float
    g_m_s2: float

    def as_exchange(self) -> dict[str, float]:
        """The constants under the exchange-format keys (docs/MODEL.md section 5) plus L_m."""
        return {
            q.m_kg: self.m_kg,
            q.l_m: self.l_m,
            q.R_m: self.R_m,
            "g": self.g_m_s2,
            q.L_m: self.L_m,
        }


DEFAULT_RECONNECT_FOR_S = 600.0


@dataclass(frozen=True)
class DaqConfig:
    """The DAQ board: where it is, how fast it samples and which input carries what."""

    port: str
    baudrate: int
    sample_rate_hz: float
    angle_input: int
    table_input: int
    tach_bit: int
    # how long a board that went away (cable knocked, board reset) is waited for while
    # streaming; 0: the run stops at once, as it did before reconnection existed
    reconnect_for_s: float = DEFAULT_RECONNECT_FOR_S


@dataclass(frozen=True)
class ShakerConfig:
    """How the shaker is driven: the amplifier's Modbus controller (``kind = "modbus"``, the
    default) or a SCPI function generator feeding the power amplifier (``kind = "scpi"``).

    Only the keys of the chosen kind are required; the other kind's keys may stay in the
    file (checked all the same).
    """

    transport: str = "tcp"
    host: str = "127.0.0.1"
    port: int = 0
    unit_id: int = 1
    serial_port: str = ""
    kind: str = "modbus"
    # kind = "scpi": a VISA resource ("TCPIP::host::5025::SOCKET", "USB0::...::INSTR", "ASRL...")
    # or "sim" (the virtual rig's generator), the amplifier gain in m of table amplitude per V of
    # generator amplitude, the reply timeout, the generator's output ceiling and its channel
    resource: str = ""
    gain_m_per_v: float = 0.0
    timeout_s: float = 1.0
    max_output_vpp: float = 10.0
    channel: int = 1


@dataclass(frozen=True)
class VirtualRigConfig:
    """Settings of the simulated rig (used only when the rig is virtual)."""

    theta_b_rad: float
    barrier: bool
    release_angle_rad: float
    noise_rad: float
    seed: int
    # physical effects the baseline model lacks, switched on in the simulation
    # (docs/MODEL.md section 6 cause name -> its parameter values), from [virtual.causes]
    causes: Mapping[str, Mapping[str, float]] = field(
        default_factory=lambda: MappingProxyType({})
    )


@dataclass(frozen=True)
class DriveTolerance:
    """How far the amplifier's read-back drive may be from the asked drive before a run stops."""

    frequency_hz: float = 0.05
    amplitude_fraction: float = 0.1  # of the asked amplitude ...
    amplitude_floor_m: float = 50e-6  # ... but never tighter than this
    settle_s: float = 5.0  # how long the output may take to reach a new setting


@dataclass(frozen=True)
class RigConfig:
    """One validated rig file."""

    source: str  # the file it came from (for messages)
    text: str  # the file verbatim (kept in every recording)
    name: str
    kind: str
    constants: RigConstants
    daq: DaqConfig
    angle_calibration: PotentiometerCalibration
    table_calibration: LaserCalibration
    tach_calibration: TachometerCalibration
    shaker: ShakerConfig
    limits: ShakerLimits
    watchdog_s: float
    virtual: VirtualRigConfig
    operator: str = ""  # who runs the rig, unless --operator says otherwise
    drive_tolerance: DriveTolerance = field(default_factory=lambda: DriveTolerance())

    @property
    def is_virtual(self) -> bool:
        """True when the devices are the virtual rig's emulators."""
        return self.kind == "virtual"

    def calibrations(self) -> dict[str, dict[str, Any]]:
        """Per-channel calibrations for a recording's metadata."""
        return {
            "angle": {"law": "potentiometer", **asdict(self.angle_calibration)},
            "table": {"law": "laser", **asdict(self.table_calibration)},
            "tach": {"law": "digital line", **asdict(self.tach_calibration)},
        }


class _Section:
    """Typed access to one TOML table, with errors that name file and key."""

    def __init__(self, source: str, prefix: str, table: Any) -> None:
        self.source = source
        self.prefix = prefix
        if not isinstance(table, dict):
            raise ConfigError(f"{source}: [{prefix}] must be a table, got {type(table).__name__}")
        self.table = table
        self.used: set[str] = set()

    def _key(self, key: str) -> str:
        return f"{self.prefix}.{key}" if self.prefix else key

    def _get(self, key: str, expected: str) -> Any:
        self.used.add(key)
        if key not in self.table:
            raise ConfigError(f"{self.source}: missing key '{self._key(key)}'; expected {expected}")
        return self.table[key]

    def _bad(self, key: str, value: Any, expected: str) -> ConfigError:
        return ConfigError(f"{self.source}: '{self._key(key)}' is {value!r}; expected {expected}")

    def section(self, key: str) -> _Section:
        return _Section(self.source, self._key(key), self._get(key, "a table"))

    def number(
        self,
        key: str,
        *,
        low: float | None = None,
        high: float | None = None,
        low_open: bool = False,
        nonzero: bool = False,
    ) -> float:
        bounds = _bounds(low, high, low_open)
        expected = ("a non-zero number" if nonzero else "a number") + _words(bounds)
        value = self._get(key, expected)
        is_number = isinstance(value, int | float) and not isinstance(value, bool)
        if not is_number or not math.isfinite(value) or value not in bounds:
            raise self._bad(key, value, expected)
        if nonzero and value == 0:
            raise self._bad(key, value, expected)
        return float(value)

    def quantity(self, key: str) -> float:
        """A number within the bounds of the registered quantity ``key``
        (:mod:`analysis.quantities`): the rig file and the model refuse the same values."""
        bounds = q.quantity(key).bounds or q.Bounds()
        expected = "a number" + _words(bounds)
        value = self._get(key, expected)
        try:
            return q.check(key, value)
        except ParameterError:
            raise self._bad(key, value, expected) from None

    def magnitude(self, key: str, smallest: float, largest: float) -> float:
        """A number of either sign whose size lies in [smallest, largest]."""
        expected = f"a number whose size is in [{smallest:g}, {largest:g}] (either sign)"
        value = self._get(key, expected)
        is_number = isinstance(value, int | float) and not isinstance(value, bool)
        if not is_number or not math.isfinite(value) or not smallest <= abs(value) <= largest:
            raise self._bad(key, value, expected)
        return float(value)

    def numbers(self, key: str) -> list[float]:
        """A list of finite numbers (may be empty)."""
        expected = "a list of numbers, e.g. [] or [0.01, -0.002]"
        value = self._get(key, expected)
        if not isinstance(value, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in value
        ):
            raise self._bad(key, value, expected)
        return [float(v) for v in value]

    def interval(self, key: str) -> tuple[float, float]:
        """A [low, high] pair with low < high."""
        values = self.numbers(key)
        if len(values) != 2 or not values[0] < values[1]:
            raise self._bad(key, values, "[low, high] with low < high")
        return values[0], values[1]

    def integer(self, key: str, *, low: int | None = None, high: int | None = None) -> int:
        expected = "an integer" + _words(_bounds(low, high, False))
        value = self._get(key, expected)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._bad(key, value, expected)
        if (low is not None and value < low) or (high is not None and value > high):
            raise self._bad(key, value, expected)
        return value

    def text(self, key: str, *, choices: tuple[str, ...] | None = None) -> str:
        expected = "one of " + ", ".join(repr(c) for c in choices) if choices else "a string"
        value = self._get(key, expected)
        if not isinstance(value, str) or (choices and value not in choices):
            raise self._bad(key, value, expected)
        return value

    def flag(self, key: str) -> bool:
        value = self._get(key, "true or false")
        if not isinstance(value, bool):
            raise self._bad(key, value, "true or false")
        return value

    def finish(self) -> None:
        """Unknown keys are mistakes (a typo would otherwise silently keep a default)."""
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            raise ConfigError(
                f"{self.source}: unknown key '{self._key(unknown[0])}'; expected one of "
                f"{', '.join(sorted(self.used))}"
            )


def _bounds(low: float | None, high: float | None, low_open: bool) -> q.Bounds:
    return q.Bounds(-math.inf if low is None else low, math.inf if high is None else high,
                    low_open)


def _words(bounds: q.Bounds) -> str:
    words = bounds.words()
    return f" {words}" if words else ""


def _virtual_causes(virtual: _Section) -> Mapping[str, Mapping[str, float]]:
    """The optional [virtual.causes] table: named causes (docs/MODEL.md section 6) and their values,
    e.g. ``coulomb_friction = { Tc_N_m = 2e-5 }``; checked against the cause registry."""
    if "causes" not in virtual.table:
        return MappingProxyType({})
    from analysis.extensions import CAUSES

    table = virtual.section("causes")
    causes: dict[str, Mapping[str, float]] = {}
    for name in list(table.table):
        if name not in CAUSES:
            raise table._bad(name, table.table[name], "a named cause: one of " + ", ".join(CAUSES))
        given = table.section(name)
        specs = CAUSES[name].parameters
        values = {
            spec.name: given.number(spec.name, low=spec.lower, high=spec.upper)
            for spec in specs
            if spec.name in given.table
        }
        given.used.update(spec.name for spec in specs)  # absent parameters take their defaults
        given.finish()
        try:
            causes[name] = MappingProxyType(CAUSES[name].values(values))
        except ParameterError as error:
            raise ConfigError(f"{virtual.source}: [virtual.causes] {error}") from None
    table.finish()
    return MappingProxyType(causes)


def _shaker_config(section: _Section, rig_kind: str) -> ShakerConfig:
    """The [shaker] table: the keys of the chosen kind required, the other kind's optional."""
    defaults = ShakerConfig()
    kind = (
        section.text("kind", choices=SHAKER_KINDS) if "kind" in section.table else defaults.kind
    )
    readers = {
        "transport": lambda key: section.text(key, choices=SHAKER_TRANSPORTS),
        "host": section.text,
        "port": lambda key: section.integer(key, low=0, high=65535),
        "unit_id": lambda key: section.integer(key, low=0, high=247),
        "serial_port": section.text,
        "resource": section.text,
        "gain_m_per_v": lambda key: section.number(
            key, low=SCPI_GAIN_M_PER_V_RANGE[0], high=SCPI_GAIN_M_PER_V_RANGE[1]
        ),
        "timeout_s": lambda key: section.number(key, low=0.05, high=60),
        "max_output_vpp": lambda key: section.number(key, low=0.01, high=SCPI_MAX_VPP),
        "channel": lambda key: section.integer(key, low=1, high=2),
    }
    required = {
        "modbus": ("transport", "host", "port", "unit_id", "serial_port"),
        "scpi": ("resource", "gain_m_per_v"),
    }[kind]
    values = {
        key: read(key)
        for key, read in readers.items()
        if key in required or key in section.table
    }
    shaker = ShakerConfig(kind=kind, **values)
    real = rig_kind == "real"
    if kind == "modbus" and shaker.transport == "rtu" and not shaker.serial_port and real:
        raise ConfigError(
            f"{section.source}: 'shaker.serial_port' is ''; expected a serial device when "
            "shaker.transport is 'rtu'"
        )
    visa = "::" in shaker.resource
    if kind == "scpi" and not (visa or (shaker.resource == "sim" and not real)):
        raise section._bad(
            "resource",
            shaker.resource,
            'a VISA resource such as "TCPIP::192.168.1.20::5025::SOCKET"'
            + ("" if real else ', or "sim" (the virtual rig\'s generator)'),
        )
    return shaker


def default_config_path() -> Path:
    """The shipped default rig file (the virtual rig)."""
    return Path(str(resources.files("rig").joinpath(DEFAULT_CONFIG_NAME)))


def load_config(path: str | Path | None = None) -> RigConfig:
    """Load and validate a rig file; ``None`` loads the shipped default (the virtual rig)."""
    path = Path(path) if path is not None else default_config_path()
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{source}: rig file not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ConfigError(f"{source}: cannot read the rig file ({error})") from None
    return parse_config(text, source)


def parse_config(text: str, source: str = "<rig file>") -> RigConfig:
    """Validate the text of a rig file (``source`` names it in errors)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{source}: not valid TOML ({error})") from None
    top = _Section(source, "", data)

    rig = top.section("rig")
    name = rig.text("name")
    kind = rig.text("kind", choices=RIG_KINDS)
    operator = rig.text("operator") if "operator" in rig.table else ""
    constants_section = rig.section("constants")
    constants = RigConstants(
        m_kg=constants_section.quantity(q.m_kg),
        l_m=constants_section.quantity(q.l_m),
        L_m=constants_section.quantity(q.L_m),
        R_m=constants_section.quantity(q.R_m),
        g_m_s2=constants_section.quantity(q.g_m_s2),
    )
    constants_section.finish()
    rig.finish()

    daq_section = top.section("daq")
    daq = DaqConfig(
        port=daq_section.text("port"),
        baudrate=daq_section.integer("baudrate", low=1200),
        sample_rate_hz=daq_section.number("sample_rate_hz", low=1.0, high=1.0e6),
        angle_input=daq_section.integer("angle_input", low=0, high=3),
        table_input=daq_section.integer("table_input", low=0, high=3),
        tach_bit=daq_section.integer("tach_bit", low=0, high=15),
        reconnect_for_s=daq_section.number("reconnect_for_s", low=0, high=86_400)
        if "reconnect_for_s" in daq_section.table
        else DEFAULT_RECONNECT_FOR_S,
    )
    if daq.angle_input == daq.table_input:
        raise ConfigError(
            f"{source}: 'daq.table_input' is {daq.table_input}; expected an input other than "
            f"daq.angle_input ({daq.angle_input})"
        )
    daq_section.finish()

    calibration = top.section("calibration")
    angle = calibration.section("angle")
    # Bounds far outside any real sensor: they catch a typo (1e308, a lost minus in an
    # exponent) before it turns every sample into inf.
    angle_calibration = PotentiometerCalibration(
        offset_v=angle.number("offset_v", low=-MAX_INPUT_V, high=MAX_INPUT_V),
        gain_rad_per_v=angle.magnitude("gain_rad_per_v", *GAIN_RAD_PER_V_RANGE),
        linearity=tuple(angle.numbers("linearity")),
    )
    angle.finish()
    table = calibration.section("table")
    table_calibration = LaserCalibration(
        zero_m=table.number("zero_m", low=-MAX_TABLE_ZERO_M, high=MAX_TABLE_ZERO_M),
        m_per_unit=table.magnitude("m_per_unit", *M_PER_UNIT_RANGE),
        unit=table.text("unit", choices=("V", "count")),
        measuring_range_m=table.interval("measuring_range_m"),
    )
    table.finish()
    calibration.finish()
    tach_calibration = TachometerCalibration(line=daq.tach_bit)

    shaker_section = top.section("shaker")
    shaker = _shaker_config(shaker_section, kind)
    shaker_section.finish()

    limits_section = top.section("limits")
    limit_values = {
        key: limits_section.number(key, low=0)
        for key in (
            "max_amplitude_m",
            "min_frequency_hz",
            "max_frequency_hz",
            "min_ramp_rate_m_s",
            "max_ramp_rate_m_s",
        )
    }
    watchdog_s = limits_section.number("watchdog_s", low=0.05, high=60)
    defaults = DriveTolerance()
    tolerance = DriveTolerance(
        **{
            name: limits_section.number(f"drive_tolerance_{name}", low=0, low_open=True)
            if f"drive_tolerance_{name}" in limits_section.table
            else getattr(defaults, name)
            for name in (q.frequency_hz, "amplitude_fraction", "amplitude_floor_m", "settle_s")
        }
    )
    limits_section.finish()
    try:
        limits = ShakerLimits(**limit_values)
    except LimitsConfigError as error:
        raise ConfigError(f"{source}: [limits] {error}") from None
    if shaker.kind == "scpi":
        needed_vpp = 2.0 * limits.max_amplitude_m / shaker.gain_m_per_v
        if needed_vpp > shaker.max_output_vpp:
            raise ConfigError(
                f"{source}: 'limits.max_amplitude_m' is {limits.max_amplitude_m!r}; expected at "
                f"most {shaker.max_output_vpp * shaker.gain_m_per_v / 2:g} m, what "
                f"shaker.max_output_vpp ({shaker.max_output_vpp:g} Vpp) gives at "
                f"shaker.gain_m_per_v ({shaker.gain_m_per_v:g} m/V)"
            )

    virtual_section = top.section("virtual")
    virtual = VirtualRigConfig(
        theta_b_rad=virtual_section.number(q.theta_b_rad, low=-0.5, high=0.5),
        barrier=virtual_section.flag("barrier"),
        release_angle_rad=virtual_section.number("release_angle_rad", low=-1.5, high=1.5),
        noise_rad=virtual_section.number("noise_rad", low=0),
        seed=virtual_section.integer("seed", low=0),
        causes=_virtual_causes(virtual_section),
    )
    virtual_section.finish()
    top.finish()

    return RigConfig(
        source=source,
        text=text,
        name=name,
        kind=kind,
        constants=constants,
        daq=daq,
        angle_calibration=angle_calibration,
        table_calibration=table_calibration,
        tach_calibration=tach_calibration,
        shaker=shaker,
        limits=limits,
        watchdog_s=watchdog_s,
        virtual=virtual,
        operator=operator,
        drive_tolerance=tolerance,
    )
