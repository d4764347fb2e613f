"""The virtual rig: pendulum physics, shaker motion and sensors, producing raw DAQ samples.

``VirtualRig`` is a :class:`hardware_sim.sample_source.SampleSource`: each
``generate(n)`` advances the physics by exactly n sample periods of the stream
clock and returns the raw ADC counts of the angle potentiometer and the table
laser, and the tachometer line.  The table follows a :class:`ShakerResponse`
(which the amplifier emulator commands), updated in short chunks with the drive
phase kept continuous.  Named causes of docs/MODEL.md section 6 are switched on in the
model (``Model(...).with_extension(...)``): dynamics causes act in the integrator,
measurement causes on the angle channel.  Thread safe: the Modbus server thread
may command the shaker while the DAQ thread generates.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace

import numpy as np

from analysis.extensions import cause
from analysis.model import Drive, Model, table_displacement
from analysis.packed import P
from analysis.simulate import SimulationStoppedError, Stepper
from hardware_sim.shaker_response import ShakerDynamics, ShakerOutput, ShakerResponse

TWO_PI = 2.0 * math.pi
CHANNELS = ("angle", "table", "tach")

# Defaults chosen so that rig/default_rig.toml's linear calibrations hold exactly:
# 1e-4 rad and 3e-6 m per count on a 16-bit +-10 V converter.
_DEFAULT_LSB_V = 20.0 / 2**16
DEFAULT_POT_GAIN_V_PER_RAD = _DEFAULT_LSB_V / 1.0e-4
DEFAULT_LASER_V_PER_M = _DEFAULT_LSB_V / 3.0e-6


@dataclass(frozen=True)
class AdcSpec:
    """A bipolar converter: ``bits`` over -range_v .. +range_v, saturating at both ends."""

    bits: int = 16
    range_v: float = 10.0

    def __post_init__(self) -> None:
        if not 8 <= self.bits <= 24:
            raise ValueError(f"AdcSpec.bits = {self.bits}: expected 8..24")
        if not (math.isfinite(self.range_v) and self.range_v > 0):
            raise ValueError(f"AdcSpec.range_v = {self.range_v}: expected > 0")

    @property
    def lsb_v(self) -> float:
        """Volts per count."""
        return 2.0 * self.range_v / 2**self.bits

    def counts(self, volts: np.ndarray) -> np.ndarray:
        """Quantize to the nearest count, clipped to the converter's range (int32)."""
        low, high = -(2 ** (self.bits - 1)), 2 ** (self.bits - 1) - 1
        return np.clip(np.floor(volts / self.lsb_v + 0.5), low, high).astype(np.int32)


@dataclass(frozen=True)
class PotentiometerOutput:
    """The potentiometer's voltage at an angle (what the driver's calibration inverts).

    ``v = offset_v + gain_v_per_rad theta + sum_k linearity_v[k] theta^(k+2)``
    """

    offset_v: float = 0.0
    gain_v_per_rad: float = DEFAULT_POT_GAIN_V_PER_RAD
    linearity_v: tuple[float, ...] = ()  # coefficients of theta^2, theta^3, ... [V / rad^k]

    def volts(self, theta_rad: np.ndarray) -> np.ndarray:
        """The wiper voltage at angle ``theta_rad``."""
        v = self.offset_v + self.gain_v_per_rad * theta_rad
        for power, coefficient in enumerate(self.linearity_v, start=2):
            v = v + coefficient * theta_rad**power
        return v


@dataclass(frozen=True)
class LaserOutput:
    """The laser's voltage at a table displacement (what the driver's calibration inverts).

    The measuring range is centred on the rest position; beyond +-range_m/2 the
    sensor's output stays at the edge of its range.
    """

    offset_v: float = 0.0
    volts_per_m: float = DEFAULT_LASER_V_PER_M
    range_m: float = 0.100

    def volts(self, x_m: np.ndarray) -> np.ndarray:
        """The sensor's analog output for displacement ``x_m``."""
        half = self.range_m / 2.0
        return self.offset_v + self.volts_per_m * np.clip(x_m, -half, half)


@dataclass(frozen=True)
class VirtualRigSettings:
    """Everything that makes one virtual rig: physics, sensors, start state, clock."""

    model: Model = field(default_factory=Model)
    sample_rate_hz: float = 2000.0
    adc: AdcSpec = field(default_factory=AdcSpec)
    potentiometer: PotentiometerOutput = field(default_factory=PotentiometerOutput)
    laser: LaserOutput = field(default_factory=LaserOutput)
    angle_noise_rad: float = 0.0  # white noise on the angle reading (standard deviation)
    table_noise_m: float = 0.0  # white noise on the laser reading
    seed: int = 0
    theta0_rad: float = 0.0
    theta_dot0_rad_s: float = 0.0
    speed_factor: float = 1.0  # for whoever paces the stream: 10 = ten times real time
    shaker: ShakerDynamics = field(default_factory=ShakerDynamics)
    drive_update_s: float = 0.002  # the table's amplitude/frequency change in steps this long

    def __post_init__(self) -> None:
        for name in ("sample_rate_hz", "speed_factor", "drive_update_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"VirtualRigSettings.{name} = {value!r}: expected > 0")
        for name in ("angle_noise_rad", "table_noise_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"VirtualRigSettings.{name} = {value!r}: expected >= 0")

    def angle_counts_to_rad(self) -> tuple[float, float]:
        """(zero_counts, rad_per_count) of the linear part of the angle chain."""
        pot = self.potentiometer
        return pot.offset_v / self.adc.lsb_v, self.adc.lsb_v / pot.gain_v_per_rad

    def table_counts_to_m(self) -> tuple[float, float]:
        """(zero_counts, m_per_count) of the laser chain."""
        return self.laser.offset_v / self.adc.lsb_v, self.adc.lsb_v / self.laser.volts_per_m


class VirtualRig:
    """Physics + sensors of the rig as a sample source for the DAQ emulator (thread safe)."""

    def __init__(self, settings: VirtualRigSettings | None = None) -> None:
        self.settings = s = settings or VirtualRigSettings()
        self._lock = threading.RLock()
        # one noise stream per channel, so that block sizes never change the samples
        self._angle_rng, self._table_rng = (
            np.random.default_rng(child) for child in np.random.SeedSequence(s.seed).spawn(2)
        )
        self._model = s.model
        self._base_p, self._drive_gains = _packed_parts(s.model)
        self.shaker = ShakerResponse(s.shaker, t0_s=0.0)
        if s.model.drive.is_forced:  # the table was already running when the simulation began
            self.shaker.settle_at(
                amplitude_m=s.model.drive.amplitude_m, frequency_hz=s.model.drive.frequency_hz
            )
        self._fs = float(s.sample_rate_hz)
        self._index = 0  # running index of the next sample
        self._rate_index0 = 0  # index and time where the current rate began
        self._rate_t0 = 0.0
        self._stepper = Stepper(s.model, s.theta0_rad, s.theta_dot0_rad_s, t0=0.0)
        self._held_at: float | None = None
        self.physics_stopped = ""  # why the simulation stopped, '' while it runs
        self._omega = 0.0
        self._phase0 = 0.0
        self._amplitude_m = 0.0
        self._measurement_carry: dict[str, dict[str, float]] = {}
        self._p = self._base_p.copy()
        self._output = self.shaker.output()

    # ------------------------------------------------------------------ SampleSource

    @property
    def sample_rate_hz(self) -> float:
        """Rate of the samples ``generate`` returns."""
        return self._fs

    @property
    def speed_factor(self) -> float:
        """How much faster than real time the stream should be paced."""
        return self.settings.speed_factor

    @property
    def time_s(self) -> float:
        """Stream time of the next sample (the physics has been integrated up to here)."""
        with self._lock:
            return self._time_of(self._index)

    @property
    def samples_generated(self) -> int:
        """Running index of the next sample."""
        with self._lock:
            return self._index

    def configure(self, sample_rate_hz: float, channels: tuple[str, ...] = CHANNELS) -> None:
        """Set the rate of later samples; time continues where it was."""
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ValueError(f"sample_rate_hz = {sample_rate_hz!r}: expected > 0")
        unknown = sorted(set(channels) - set(CHANNELS))
        if unknown:
            raise ValueError(f"unknown channel(s) {unknown}; the rig has {list(CHANNELS)}")
        with self._lock:
            self._rate_t0 = self._time_of(self._index)
            self._rate_index0 = self._index
            self._fs = float(sample_rate_hz)

    def generate(self, n: int) -> dict[str, np.ndarray]:
        """The next ``n`` samples: angle and table as int32 ADC counts, tach as bool."""
        if n < 0:
            raise ValueError(f"n = {n}: expected >= 0")
        with self._lock:
            index = np.arange(self._index, self._index + n, dtype=np.int64)
            t = self._rate_t0 + (index - self._rate_index0) / self._fs
            theta = np.empty(n)
            table = np.empty(n)
            tach = np.zeros(n, dtype=bool)
            chunk = max(1, round(self.settings.drive_update_s * self._fs))
            start = 0
            while start < n:
                # chunk boundaries on the global sample grid: results do not depend on n
                rel = self._index + start - self._rate_index0
                stop = min(n, start + chunk - rel % chunk)
                self._update_drive(float(t[start]))
                theta[start:stop] = self._angle(t[start:stop])
                table[start:stop], tach[start:stop] = self._table(t[start:stop])
                start = stop
            self._index += n
            return {
                "angle": self._angle_counts(t, theta),
                "table": self._table_counts(table),
                "tach": tach,
            }

    # ------------------------------------------------------------------ operator actions

    def release(self, theta0_rad: float, theta_dot0_rad_s: float = 0.0) -> None:
        """The operator lets go of the pendulum at ``theta0_rad`` (takes effect now)."""
        with self._lock:
            t = self._time_of(self._index)
            self._stepper = Stepper(self._model, float(theta0_rad), float(theta_dot0_rad_s), t0=t)
            self._stepper.set_packed(self._p, phase0=self._phase0)
            self._held_at = None
            self.physics_stopped = ""

    def hold(self, theta_rad: float) -> None:
        """The operator holds the pendulum still at ``theta_rad`` until ``release``."""
        with self._lock:
            self._held_at = float(theta_rad)

    def set_barrier(self, present: bool) -> None:
        """Put the barrier in (True) or take it out."""
        with self._lock:
            self.set_model(replace(self._model, barrier=bool(present)))

    def set_model(self, model: Model) -> None:
        """New rig constants, barrier or causes; the pendulum's state is kept.

        The drive comes from the shaker: ``model.drive`` only sets the harmonic
        content (h2, phi2) of the table motion.
        """
        with self._lock:
            self._model = model
            self._base_p, self._drive_gains = _packed_parts(model)
            self._p = self._base_p.copy()
            self._write_drive(self._p)
            self._stepper.set_packed(self._p, phase0=self._phase0)

    @property
    def model(self) -> Model:
        """The model currently integrated."""
        return self._model

    def advance(self, duration_s: float) -> float:
        """Let whole sample periods pass unread (an idle board); returns the time advanced."""
        with self._lock:
            n = math.floor(duration_s * self._fs)
            total = n
            while n > 0:
                step = min(n, 1 << 16)
                self.generate(step)
                n -= step
            return total / self._fs

    def state(self) -> tuple[float, float, float]:
        """(t, theta, theta_dot) of the physics at the stream time."""
        with self._lock:
            if self._held_at is not None:
                return self._time_of(self._index), self._held_at, 0.0
            return self._stepper.t, self._stepper.theta, self._stepper.theta_dot

    @property
    def table_output(self) -> ShakerOutput:
        """The shaker output applied to the current chunk."""
        with self._lock:
            return self._output

    # ------------------------------------------------------------------ internals

    def _time_of(self, index: int) -> float:
        return self._rate_t0 + (index - self._rate_index0) / self._fs

    def _update_drive(self, t: float) -> None:
        """Bring the table's amplitude and frequency to the shaker output at ``t``."""
        out = self.shaker.advance_to(t)
        self._output = out
        omega = TWO_PI * out.frequency_hz
        if omega != self._omega or out.amplitude_m != self._amplitude_m:
            phase = self._omega * t + self._phase0
            self._phase0 = math.remainder(phase - omega * t, TWO_PI) if omega else phase
            self._omega = omega
            self._amplitude_m = out.amplitude_m
            self._write_drive(self._p)
            if self._held_at is None:
                self._stepper.set_packed(self._p, phase0=self._phase0)

    def _write_drive(self, p: np.ndarray) -> None:
        g1, g2 = self._drive_gains
        p[P.A1] = g1 * self._amplitude_m
        p[P.A2] = g2 * self._amplitude_m
        p[P.OMEGA_DRIVE] = self._omega
        p[P.PHASE0] = self._phase0

    def _angle(self, t: np.ndarray) -> np.ndarray:
        if self._held_at is not None:
            return np.full(t.size, self._held_at)
        first = 0
        out = np.empty(t.size)
        while first < t.size and t[first] <= self._stepper.t:  # the start state itself
            out[first] = self._stepper.theta
            first += 1
        if first < t.size:
            try:
                theta, _ = self._stepper.advance(t[first:])
            except SimulationStoppedError as error:
                # e.g. driven over the top: the rig's pendulum would be caught by hand
                self.physics_stopped = str(error)
                self._held_at = math.remainder(self._stepper.theta, TWO_PI)
                theta = np.full(t.size - first, self._held_at)
            out[first:] = theta
        return out

    def _table(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = self._p
        phase = self._omega * t + self._phase0
        x = table_displacement(phase, p[P.A1], p[P.A2], p[P.PHI2])
        tach = np.zeros(t.size, dtype=bool)
        if self._omega > 0:
            cycle = np.floor(phase / TWO_PI)
            previous = np.empty_like(cycle)
            previous[1:] = cycle[:-1]
            # the sample before this chunk, on the same (continuous) phase line
            before = self._omega * (t[0] - 1.0 / self._fs) + self._phase0
            previous[0] = math.floor(before / TWO_PI)
            tach = cycle > previous
        return x, tach

    def _angle_counts(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        s = self.settings
        measured = theta
        for name, given in self._model.extensions.items():
            c = cause(name)
            if c.measurement is None:
                continue
            # a cause with a state (a filter) carries it from one block to the next
            measured = c.measurement(t, measured, c.values(given), None,
                                     self._measurement_carry.setdefault(name, {}))
        if s.angle_noise_rad > 0:
            measured = measured + self._angle_rng.normal(0.0, s.angle_noise_rad, measured.size)
        return s.adc.counts(s.potentiometer.volts(measured))

    def _table_counts(self, x: np.ndarray) -> np.ndarray:
        s = self.settings
        if s.table_noise_m > 0:
            x = x + self._table_rng.normal(0.0, s.table_noise_m, x.size)
        return s.adc.counts(s.laser.volts(x))


def compile_physics(settings: VirtualRigSettings) -> None:
    """Compile the numba physics on a throwaway rig swinging into the barrier.

    The first integration compiles (tens of seconds on a fresh install or after the
    model code changed, holding the interpreter meanwhile); doing it before serving
    keeps a device's first frames and the first shaker ramp from waiting for it.
    """
    rig = VirtualRig(replace(settings, seed=0))
    rig.release(-0.3)
    rig.generate(max(1, round(settings.sample_rate_hz)))


def _packed_parts(model: Model) -> tuple[np.ndarray, tuple[float, float]]:
    """Packed vector with the drive zeroed, and the per-metre table amplitudes (A1, A2).

    Packing a unit drive lets the excitation causes (second harmonic, amplitude
    error) scale the shaker's output exactly as they scale a stated drive.
    """
    unit = replace(model, drive=Drive(1.0, 1.0, model.drive.h2, model.drive.phi2_rad))
    p = unit.pack()
    gains = (float(p[P.A1]), float(p[P.A2]))
    p[P.A1] = p[P.A2] = p[P.OMEGA_DRIVE] = p[P.PHASE0] = 0.0
    return p, gains
