"""Role drivers on one DAQ board: potentiometer angle, laser displacement, tachometer.

Each role is an :class:`~drivers.interfaces.InputStream` with its own calibration,
and all share the stream of one :class:`~drivers.daq.DaqBoard` (declared once,
whatever its backend).  Counts become volts with the ADC scale the board reports;
volts become SI units with the role's calibration, a small validated dataclass.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from drivers.daq import DaqBoard, RawChunk, RoleQueue
from drivers.interfaces import PulseBlock, SampleBlock, StreamStatus

FLAG_AT_RAIL = 1  # the ADC reading is saturated: the true value is beyond it
FLAG_OUT_OF_RANGE = 2  # the reading lies outside the sensor's measuring range
FLAG_NOT_FINITE = 4  # the calibrated value is infinite or NaN (set by the recorder)


def _require_finite(owner: str, **values: float) -> None:
    for name, value in values.items():
        real = isinstance(value, numbers.Real) and not isinstance(value, bool)
        if not real or not math.isfinite(value):
            raise ValueError(f"{owner}.{name}={value!r} must be a finite number")


@dataclass(frozen=True)
class PotentiometerCalibration:
    """Angle from the potentiometer voltage ``v``.

    ``a = gain_rad_per_v * (v - offset_v)``, then the linearity correction
    ``theta = a + c[0] a**2 + c[1] a**3 + ...`` with ``c = linearity``
    (empty: the potentiometer is taken as linear).
    """

    offset_v: float = 0.0
    gain_rad_per_v: float = 0.3
    linearity: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "linearity", tuple(self.linearity))  # a list from a file is fine
        _require_finite("PotentiometerCalibration", offset_v=self.offset_v)
        _require_finite("PotentiometerCalibration", gain_rad_per_v=self.gain_rad_per_v)
        if self.gain_rad_per_v == 0:
            raise ValueError("PotentiometerCalibration.gain_rad_per_v must not be 0")
        for k, coefficient in enumerate(self.linearity):
            _require_finite("PotentiometerCalibration", **{f"linearity[{k}]": coefficient})

    def angle_rad(self, volts: np.ndarray) -> np.ndarray:
        """Angle (rad) for potentiometer voltages."""
        linear = self.gain_rad_per_v * (np.asarray(volts, dtype=np.float64) - self.offset_v)
        if not self.linearity:
            return linear
        # Horner on a*(1 + c0 a + c1 a^2 + ...): one pass, no powers.
        correction = np.zeros_like(linear)
        for coefficient in reversed(self.linearity):
            correction = (correction + coefficient) * linear
        return linear + correction * linear


@dataclass(frozen=True)
class LaserCalibration:
    """Displacement from the laser's output: ``x = zero_m + m_per_unit * reading``.

    ``unit`` is ``'V'`` (analog output on a DAQ input) or ``'count'`` (the sensor's
    digital value).  Readings outside ``measuring_range_m`` are flagged, not hidden.
    """

    zero_m: float = 0.0
    m_per_unit: float = 0.005  # e.g. 100 mm over +-10 V
    unit: str = "V"
    measuring_range_m: tuple[float, float] = (-0.05, 0.05)

    def __post_init__(self) -> None:
        _require_finite("LaserCalibration", zero_m=self.zero_m, m_per_unit=self.m_per_unit)
        if self.m_per_unit == 0:
            raise ValueError("LaserCalibration.m_per_unit must not be 0")
        if self.unit not in ("V", "count"):
            raise ValueError(f"LaserCalibration.unit={self.unit!r} must be 'V' or 'count'")
        if len(self.measuring_range_m) != 2:
            raise ValueError(
                f"LaserCalibration.measuring_range_m={self.measuring_range_m!r} must be (low, high)"
            )
        object.__setattr__(self, "measuring_range_m", tuple(self.measuring_range_m))
        low, high = self.measuring_range_m
        _require_finite("LaserCalibration", measuring_range_low=low, measuring_range_high=high)
        if not low < high:
            raise ValueError(
                f"LaserCalibration.measuring_range_m={self.measuring_range_m} must be (low, high)"
                " with low < high"
            )

    def displacement_m(self, reading: np.ndarray) -> np.ndarray:
        """Displacement (m) for readings in ``unit``."""
        return self.zero_m + self.m_per_unit * np.asarray(reading, dtype=np.float64)

    def range_flags(self, displacement_m: np.ndarray) -> np.ndarray:
        """FLAG_OUT_OF_RANGE where a displacement lies outside the measuring range, else 0."""
        low, high = self.measuring_range_m
        return np.where(
            (displacement_m < low) | (displacement_m > high), FLAG_OUT_OF_RANGE, 0
        ).astype(np.uint8)


@dataclass(frozen=True)
class TachometerCalibration:
    """Which digital line carries the once-per-period pulse (rising edge = drive phase 0)."""

    line: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.line, int) or not 0 <= self.line < 16:
            raise ValueError(f"TachometerCalibration.line={self.line!r} must be 0..15")


class _BoardRole:
    """What every role shares: its subscription to the board's stream and its status."""

    channel: str
    unit: str

    def __init__(self, board: DaqBoard, name: str) -> None:
        self.board = board
        self.channel = name
        self._subscription: RoleQueue | None = None
        self._last: RoleQueue | None = None

    @property
    def sample_rate_hz(self) -> float:
        return self.board.sample_rate_hz

    def start(self) -> None:
        self.attach(start=True)

    def attach(self, *, start: bool = True) -> None:
        """Subscribe to the board's stream (and start it when ``start`` and not yet running)."""
        if self._subscription is None:
            self._on_start()
            self._subscription = self.board.subscribe(start=start)
            self._last = self._subscription

    def stop(self) -> None:
        if self._subscription is not None:
            subscription, self._subscription = self._subscription, None
            self.board.unsubscribe(subscription)

    def _on_start(self) -> None:
        """Reset per-stream state (e.g. the tachometer's last level)."""

    def _take(self, timeout_s: float) -> tuple[RawChunk, int] | None:
        if self._subscription is None:
            raise RuntimeError(f"{self.channel}: read() before start()")
        return self._subscription.take(timeout_s, self.board)

    def status(self) -> StreamStatus:
        board = self.board.status()
        mine = self._last
        return StreamStatus(
            running=self._subscription is not None and board.running,
            samples_received=0 if mine is None else mine.samples_received,
            samples_lost=0 if mine is None else mine.samples_lost,
            frames_rejected=board.frames_rejected,
            message=board.message,
            reconnecting=board.reconnecting,
        )


class _AnalogRole(_BoardRole):
    def __init__(self, board: DaqBoard, analog_channel: int, name: str) -> None:
        super().__init__(board, name)
        self.analog_channel = analog_channel
        self._column = board.column_of(analog_channel)  # unknown channel: clear error now

    def read(self, timeout_s: float = 0.1) -> SampleBlock | None:
        taken = self._take(timeout_s)
        if taken is None:
            return None
        chunk, lost = taken
        counts = chunk.analog[:, self._column]
        values, flags = self._convert(counts)
        rate = self.board.sample_rate_hz
        return SampleBlock(
            channel=self.channel,
            first_index=chunk.first_index,
            timestamp_s=chunk.first_index / rate,
            sample_rate_hz=rate,
            raw=counts,
            values=values,
            lost_before=lost,
            flags=flags,
            outage_s=chunk.outage_s,
        )

    def _convert(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The role's values of a block's ADC counts, and its per-sample flags (or None)."""
        raise NotImplementedError


class AnalogVoltageInput(_AnalogRole):
    """A plain analog input in volts (spare channels, monitoring)."""

    unit = "V"

    def __init__(self, board: DaqBoard, analog_channel: int, name: str | None = None) -> None:
        super().__init__(board, analog_channel, name or f"ai{analog_channel}")

    def _convert(self, counts: np.ndarray) -> tuple[np.ndarray, None]:
        return counts * self.board.volts_per_count, None


class PotentiometerAngleSensor(_AnalogRole):
    """Pendulum angle (rad) from a potentiometer on one analog input of the board."""

    unit = "rad"

    def __init__(
        self,
        board: DaqBoard,
        analog_channel: int,
        calibration: PotentiometerCalibration,
        name: str = "angle",
    ) -> None:
        super().__init__(board, analog_channel, name)
        self.calibration = calibration

    def _convert(self, counts: np.ndarray) -> tuple[np.ndarray, None]:
        return self.calibration.angle_rad(counts * self.board.volts_per_count), None


class LaserDisplacementSensor(_AnalogRole):
    """Shake-table displacement (m) from a laser sensor, with per-sample range flags.

    ``flags`` has FLAG_AT_RAIL where the ADC is saturated and FLAG_OUT_OF_RANGE where
    the value lies outside the sensor's measuring range.
    """

    unit = "m"

    def __init__(
        self,
        board: DaqBoard,
        analog_channel: int,
        calibration: LaserCalibration,
        name: str = "table",
    ) -> None:
        super().__init__(board, analog_channel, name)
        self.calibration = calibration

    def _convert(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        reading = counts * self.board.volts_per_count if self.calibration.unit == "V" else counts
        values = self.calibration.displacement_m(reading)
        flags = self.calibration.range_flags(values)
        low, high = self.board.adc_limits
        flags[(counts <= low) | (counts >= high)] |= FLAG_AT_RAIL
        return values, flags


class Tachometer(_BoardRole):
    """Rising edges of the tachometer line, as running sample indices and device times.

    An edge needs the level of the sample before it; that level is carried from
    one block to the next, and forgotten across a gap (an edge inside lost samples
    is lost, never guessed).
    """

    unit = "s"

    def __init__(
        self,
        board: DaqBoard,
        calibration: TachometerCalibration | None = None,
        name: str = "tach",
    ) -> None:
        super().__init__(board, name)
        self.calibration = calibration or TachometerCalibration()
        self._previous_high: bool | None = None

    def _on_start(self) -> None:
        self._previous_high = None

    def read(self, timeout_s: float = 0.1) -> PulseBlock | None:
        taken = self._take(timeout_s)
        if taken is None:
            return None
        chunk, lost = taken
        high = (chunk.digital >> self.calibration.line) & 1 != 0
        before = lost == 0 and self._previous_high is not None
        rising = np.flatnonzero(high[1:] & ~high[:-1]) + 1
        if before and high[0] and not self._previous_high:
            rising = np.concatenate(([0], rising))
        self._previous_high = bool(high[-1])
        edges = chunk.first_index + rising.astype(np.int64)
        return PulseBlock(
            channel=self.channel,
            first_index=chunk.first_index,
            end_index=chunk.end_index,
            edge_indices=edges,
            edge_times_s=edges / self.board.sample_rate_hz,
            lost_before=lost,
            outage_s=chunk.outage_s,
        )
