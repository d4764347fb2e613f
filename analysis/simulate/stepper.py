"""Streaming simulation for the virtual rig: advance a running pendulum to requested times.

The stepper keeps the integrator's state between calls; outputs come from the
dense output of the steps, so asking for many closely spaced sample times
(200 kHz) costs a few flops per sample on top of the steps the accuracy needs.
Parameters (drive amplitude and frequency, barrier, causes) may change between
calls; the drive phase stays continuous unless a new one is given.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.model import Model
from analysis.packed import P
from analysis.simulate import integrator as ig
from analysis.simulate.result import ContactEvents, StickEvents
from analysis.simulate.simulation import check_step_settings


class SimulationStoppedError(RuntimeError):
    """The pendulum left the model's regime (e.g. over the top) or the step size underflowed."""


class Stepper:
    """A pendulum simulation advanced on demand: ``advance(times)`` -> (theta, theta_dot)."""

    def __init__(
        self,
        model: Model,
        theta0: float,
        theta_dot0: float = 0.0,
        t0: float = 0.0,
        rtol: float = 1e-9,
        atol: float = 1e-11,
        max_step_s: float = math.inf,
    ) -> None:
        if not (math.isfinite(theta0) and math.isfinite(theta_dot0) and math.isfinite(t0)):
            raise ValueError(
                f"initial state t0={t0!r}, theta0={theta0!r}, "
                f"theta_dot0={theta_dot0!r} must be finite"
            )
        check_step_settings(rtol, atol, max_step_s)
        p = np.ascontiguousarray(model.pack(), dtype=float)
        state = ig.new_state(float(t0), float(theta0), float(theta_dot0), p)
        self._run = ig.Run(p, state, ig.StepControl(rtol, atol, max_step_s))
        self._t = float(t0)

    # ------------------------------------------------------------------ state
    @property
    def t(self) -> float:
        """Current time [s] (the last time advanced to)."""
        return self._t

    @property
    def theta(self) -> float:
        """Current angle [rad]."""
        return float(ig.state_at(self._run.state, self._t)[0])

    @property
    def theta_dot(self) -> float:
        """Current angular velocity [rad/s]."""
        return float(ig.state_at(self._run.state, self._t)[1])

    @property
    def in_contact(self) -> bool:
        """True while the pendulum presses into the barrier."""
        return self._run.state[ig.S_CONTACT] != 0.0

    @property
    def drive_phase(self) -> float:
        """Current drive phase (Omega t + phase0) mod 2 pi [rad]."""
        return (self._run.p[P.OMEGA_DRIVE] * self._t + self._run.p[P.PHASE0]) % (2.0 * math.pi)

    @property
    def packed(self) -> np.ndarray:
        """A copy of the packed parameter vector in use (PHASE0 included)."""
        return self._run.p.copy()

    @property
    def status(self) -> str:
        """ "ok" while running; why it stopped otherwise."""
        return ig.STATUS_NAMES[int(self._run.state[ig.S_STATUS])]

    # ------------------------------------------------------------------ changes
    def set_model(self, model: Model, phase0: float | None = None) -> None:
        """Use new parameters from now on; the state is kept (see :meth:`set_packed`)."""
        self.set_packed(model.pack(), phase0)

    def set_packed(self, p: np.ndarray, phase0: float | None = None) -> None:
        """Use a new packed parameter vector from now on, keeping the state.

        ``phase0`` None keeps the drive phase continuous at the current time (the
        vector's own PHASE0 is replaced); a number sets PHASE0 explicitly.
        """
        p = np.array(p, dtype=float)
        if p.shape != (P.SIZE,):
            raise ValueError(f"packed vector has shape {p.shape}; expected ({int(P.SIZE)},)")
        if phase0 is None:
            phase_now = self._run.p[P.OMEGA_DRIVE] * self._t + self._run.p[P.PHASE0]
            phase0 = phase_now - p[P.OMEGA_DRIVE] * self._t
        p[P.PHASE0] = math.remainder(phase0, 2.0 * math.pi)
        theta, theta_dot = ig.state_at(self._run.state, self._t)
        self._run.p = p
        ig.restart(self._run.state, self._t, theta, theta_dot, p)

    def set_state(self, theta: float, theta_dot: float = 0.0) -> None:
        """Put the pendulum at (theta, theta_dot) now, e.g. the operator releases it."""
        if not (math.isfinite(theta) and math.isfinite(theta_dot)):
            raise ValueError(f"state ({theta!r}, {theta_dot!r}) must be finite")
        self._run.state[ig.S_CONTACT] = 0.0  # a contact in progress is abandoned, not reported
        self._run.state[ig.S_STATUS] = ig.STATUS_OK
        ig.restart(self._run.state, self._t, float(theta), float(theta_dot), self._run.p)

    # ------------------------------------------------------------------ stepping
    def advance(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integrate to the increasing ``times`` (>= current t); return theta, theta_dot there.

        Raises SimulationStoppedError when the pendulum leaves the model's regime
        (``status`` says why); ``set_state`` starts it again.
        """
        times = np.ascontiguousarray(times, dtype=float)
        if times.ndim != 1:
            raise ValueError(f"times must be one-dimensional, got shape {times.shape}")
        theta = np.empty(times.size)
        theta_dot = np.empty(times.size)
        if times.size == 0:
            return theta, theta_dot
        if times[0] < self._t or np.any(np.diff(times) < 0):
            raise ValueError(
                f"times must be non-decreasing and start at or after the current time "
                f"{self._t!r} (first requested {times[0]!r})"
            )
        if self.status != "ok":
            raise SimulationStoppedError(f"the simulation has stopped: {self.status}")
        written = self._run.advance(times, theta, theta_dot, float(times[-1]))
        if written < times.size:
            self._t = float(times[written - 1]) if written else self._t
            raise SimulationStoppedError(
                f"the simulation stopped at t = {self._run.state[ig.S_TB]:.6g} s: {self.status}"
            )
        self._t = float(times[-1])
        return theta, theta_dot

    def _pop_rows(self) -> np.ndarray:
        """Event rows that ended by the current time; later ones (the integrator may have
        stepped past ``t``) stay for the next pop."""
        run = self._run
        rows = run.events[: run.n_events].copy()
        done = rows[:, ig.EV_T_OUT] <= self._t
        pending = rows[~done]
        run.events[: pending.shape[0]] = pending
        run.n_events = pending.shape[0]
        return rows[done]

    def pop_contacts(self) -> ContactEvents:
        """Contacts completed since the last pop (stick intervals are dropped with them)."""
        return ContactEvents.from_rows(self._pop_rows())

    def pop_events(self) -> tuple[ContactEvents, StickEvents]:
        """Contacts and stick intervals completed since the last pop."""
        rows = self._pop_rows()
        return ContactEvents.from_rows(rows), StickEvents.from_rows(rows)
