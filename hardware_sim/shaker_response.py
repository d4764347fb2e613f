"""Amplifier + shaker dynamics: the output follows its setpoints with finite slew and settling.

The controller ramps its internal command toward the target (amplitude at the
configured ramp rate, frequency at a fixed slew limit); the mechanical output then
settles to that command with a first-order lag.  Both pieces have closed forms, so
``advance_to`` is exact for any time step, from a 5 us DAQ sample to an hour idle.
Time is passed in by the caller: the virtual rig advances it with its stream clock,
a stand-alone emulator with the wall clock.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

from analysis import quantities as q

AT_ZERO_M = 0.5e-6  # below this the output counts as stopped: it reads 0 in whole micrometres


@dataclass(frozen=True)
class ShakerDynamics:
    """Fixed properties of the amplifier and shaker (not settable over the bus)."""

    frequency_slew_hz_s: float = 20.0  # how fast the controller moves the frequency
    amplitude_tau_s: float = 0.05  # first-order settling of the mechanical amplitude
    frequency_tau_s: float = 0.02  # first-order settling of the measured frequency
    default_ramp_rate_m_s: float = 0.005

    def __post_init__(self) -> None:
        for name in ("frequency_slew_hz_s", "default_ramp_rate_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ShakerDynamics.{name} = {value!r}: must be > 0")
        for name in ("amplitude_tau_s", "frequency_tau_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"ShakerDynamics.{name} = {value!r}: must be >= 0")


@dataclass(frozen=True)
class ShakerOutput:
    """The shaker's actual output at time ``t_s``."""

    t_s: float
    amplitude_m: float
    frequency_hz: float
    ramping: bool  # still moving toward the targets

    @property
    def at_zero(self) -> bool:
        """True when the table has (practically) stopped."""
        return self.amplitude_m < AT_ZERO_M


def _lagged_ramp(
    ref0: float, out0: float, target: float, rate: float, tau: float, dt: float
) -> tuple[float, float]:
    """Command ramped toward ``target`` at ``rate``, output lagging by ``tau``; state after dt."""
    if dt <= 0:
        return ref0, out0
    gap = target - ref0
    slope = math.copysign(rate, gap) if gap != 0 else 0.0
    t_hit = abs(gap) / rate if rate > 0 else math.inf
    ramp_time = min(dt, t_hit)

    def follow(ref_start: float, out_start: float, s: float, t: float) -> float:
        # y' = (r0 + s t - y) / tau has the solution r(t) - s tau + (y0 - r0 + s tau) e^(-t/tau)
        if tau <= 0:
            return ref_start + s * t
        return ref_start + s * t - s * tau + (out_start - ref_start + s * tau) * math.exp(-t / tau)

    out = follow(ref0, out0, slope, ramp_time)
    ref = ref0 + slope * ramp_time
    if dt > t_hit:
        ref = target
        out = follow(target, out, 0.0, dt - t_hit)
    return ref, out


class ShakerResponse:
    """Thread-safe state of the amplifier output; targets change now, the output follows.

    ``set_targets`` acts at the time the response has been advanced to; callers in
    other threads (the Modbus server) therefore never move the clock.
    """

    def __init__(self, dynamics: ShakerDynamics | None = None, t0_s: float = 0.0) -> None:
        self.dynamics = dynamics or ShakerDynamics()
        self._lock = threading.Lock()
        self._t = float(t0_s)
        self._amp_ref = self._amp_out = 0.0
        self._freq_ref = self._freq_out = 0.0
        self._amp_target = 0.0
        self._freq_target = 0.0
        self._ramp_rate = self.dynamics.default_ramp_rate_m_s

    def set_targets(
        self,
        *,
        amplitude_m: float | None = None,
        frequency_hz: float | None = None,
        ramp_rate_m_s: float | None = None,
    ) -> None:
        """New targets from now on (None keeps a target)."""
        with self._lock:
            if amplitude_m is not None:
                self._amp_target = q.check(q.amplitude_m, amplitude_m)
            if frequency_hz is not None:
                self._freq_target = q.check(q.frequency_hz, frequency_hz)
            if ramp_rate_m_s is not None:
                rate = float(ramp_rate_m_s)
                if not (math.isfinite(rate) and rate > 0):
                    raise ValueError(f"ramp_rate_m_s = {ramp_rate_m_s!r}: must be > 0")
                self._ramp_rate = rate

    def settle_at(self, *, amplitude_m: float, frequency_hz: float) -> None:
        """Jump to a settled output (the table was already running when the simulation started)."""
        with self._lock:
            self._amp_target = self._amp_ref = self._amp_out = q.check(q.amplitude_m, amplitude_m)
            self._freq_target = self._freq_ref = self._freq_out = q.check(
                q.frequency_hz, frequency_hz
            )

    @property
    def targets(self) -> tuple[float, float, float]:
        """(amplitude_m, frequency_hz, ramp_rate_m_s) being approached."""
        with self._lock:
            return self._amp_target, self._freq_target, self._ramp_rate

    @property
    def t_s(self) -> float:
        """Time the response has been advanced to."""
        with self._lock:
            return self._t

    def advance_to(self, t_s: float) -> ShakerOutput:
        """Evolve the output up to ``t_s`` (earlier times leave it unchanged) and return it."""
        with self._lock:
            dt = t_s - self._t
            if dt > 0:
                d = self.dynamics
                self._amp_ref, self._amp_out = _lagged_ramp(
                    self._amp_ref,
                    self._amp_out,
                    self._amp_target,
                    self._ramp_rate,
                    d.amplitude_tau_s,
                    dt,
                )
                self._freq_ref, self._freq_out = _lagged_ramp(
                    self._freq_ref,
                    self._freq_out,
                    self._freq_target,
                    d.frequency_slew_hz_s,
                    d.frequency_tau_s,
                    dt,
                )
                self._t = t_s
            return self._output()

    def output(self) -> ShakerOutput:
        """The output at the time the response has been advanced to."""
        with self._lock:
            return self._output()

    def _output(self) -> ShakerOutput:
        ramping = (
            self._amp_ref != self._amp_target
            or self._freq_ref != self._freq_target
            or abs(self._amp_out - self._amp_target) > 1e-7
            or abs(self._freq_out - self._freq_target) > 1e-4
        )
        return ShakerOutput(self._t, max(self._amp_out, 0.0), max(self._freq_out, 0.0), ramping)
