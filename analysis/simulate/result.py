"""Result objects of the simulator: samples, contact and stick events, Poincare samples."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.simulate import integrator as ig


def _columns(rows: np.ndarray, kind: int) -> np.ndarray:
    """The rows of one event kind, transposed into a new array: one contiguous column per
    field, none sharing memory with the integrator's event buffer."""
    return np.ascontiguousarray(rows[rows[:, ig.EV_KIND] == kind].T)


@dataclass(frozen=True)
class ContactEvents:
    """Completed barrier contacts, one entry per contact (arrays of equal length).

    Entry and exit states lie on the contact surface (theta = theta_b to rounding);
    ``grazing`` marks contacts that a sign test at step ends would have missed:
    the step's dense output had its maximum beyond the surface while the step
    ended in free flight.
    """

    t_in: np.ndarray
    t_out: np.ndarray
    theta_in: np.ndarray
    theta_out: np.ndarray
    theta_dot_in: np.ndarray
    theta_dot_out: np.ndarray
    delta_max_m: np.ndarray
    grazing: np.ndarray

    @property
    def count(self) -> int:
        """Number of completed contacts."""
        return int(self.t_in.size)

    @property
    def duration_s(self) -> np.ndarray:
        """Contact durations t_out - t_in."""
        return self.t_out - self.t_in

    @classmethod
    def from_rows(cls, rows: np.ndarray) -> ContactEvents:
        """Select the contact rows of an integrator event buffer."""
        columns = _columns(rows, ig.KIND_CONTACT)
        return cls(
            t_in=columns[ig.EV_T_IN],
            t_out=columns[ig.EV_T_OUT],
            theta_in=columns[ig.EV_TH_IN],
            theta_out=columns[ig.EV_TH_OUT],
            theta_dot_in=columns[ig.EV_OM_IN],
            theta_dot_out=columns[ig.EV_OM_OUT],
            delta_max_m=columns[ig.EV_DELTA_MAX],
            grazing=columns[ig.EV_GRAZING] != 0.0,
        )


@dataclass(frozen=True)
class StickEvents:
    """Completed Coulomb stick intervals: stuck at ``theta`` from ``t_start`` to ``t_end``."""

    t_start: np.ndarray
    t_end: np.ndarray
    theta: np.ndarray

    @property
    def count(self) -> int:
        """Number of completed stick intervals."""
        return int(self.t_start.size)

    @classmethod
    def from_rows(cls, rows: np.ndarray) -> StickEvents:
        """Select the stick rows of an integrator event buffer."""
        columns = _columns(rows, ig.KIND_STICK)
        return cls(
            t_start=columns[ig.EV_T_IN],
            t_end=columns[ig.EV_T_OUT],
            theta=columns[ig.EV_TH_IN],
        )


@dataclass(frozen=True)
class Trajectory:
    """A time series of the state: times [s], theta [rad], theta' [rad/s]."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray


@dataclass(frozen=True)
class SimulationResult:
    """What :func:`analysis.simulate.simulate` returns.

    ``t`` is the simulation time (the record starts at ``record_start_s``, the
    transient ``skip_s`` rounded up to whole drive periods for forced models);
    ``theta``/``theta_dot`` are the uniform samples at ``fs_hz``, interpolated on the
    integrator's dense output.  ``poincare`` holds one sample per drive period at the
    chosen drive phase (empty when unforced or not asked for); ``dense`` every step
    end when asked for.  ``status`` is "ok", "over_the_top" (the pendulum left the
    experiment's regime; samples after that are dropped), "max_steps" or
    "step_size_underflow".
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    fs_hz: float
    record_start_s: float
    contacts: ContactEvents
    sticks: StickEvents
    poincare: Trajectory
    dense: Trajectory | None
    n_steps: int
    n_rejected: int
    status: str
    final_state: tuple[float, float, float]

    @property
    def ok(self) -> bool:
        """True when the run reached its end without leaving the model's regime."""
        return self.status == "ok"
