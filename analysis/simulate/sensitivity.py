"""Forward sensitivities of a run: the derivatives of (theta, theta') at every requested time
with respect to the initial state and to chosen entries of the packed parameter vector.

One plain compiled run records its segments; the variational equations are then carried
along those same steps (:mod:`analysis.simulate.variational`), through every contact with
the saltation matrix of the event, at a cost of a few plain runs whatever the number of
parameters.  The derivatives are those of the integrator's own discrete solution (its
steps, its dense output), so they agree with differences of its runs far better than
differences of runs agree with each other::

    settings = SensitivitySettings(parameters=("K", "MU0", "THETA_B"))
    run = simulate_sensitivities(model.pack(), 0.3, 0.0, times, settings=settings)
    run.jacobian[:, 0, :]   # d theta / d (theta0, theta_dot0, K, MU0, THETA_B)

Parameters are named by the packed vector's entries (``analysis.packed.P``); a named
cause's parameter enters through the entries its term writes (docs/MODEL.md section 6:
``c2_per_rad`` is ``C2``, ``theta_b_rad`` is ``THETA_B``, ``n`` and ``K_n`` are
``EXPONENT`` and ``K``, ``c_N_s_per_m`` is ``C_VISCOUS``, ``h2`` and ``phi2_rad`` are
``A2`` / A and ``PHI2``, ``eps`` moves ``A1`` and ``A2``), the rig's through theirs (zeta
through ``TWO_ZETA_OMEGA``): the caller applies the chain rule.  ``THETA_B`` moves the
contact surface and ``SIN_THETA_B`` with it.  Coulomb friction (its stick and slip
events) is not supported yet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.packed import P
from analysis.simulate import integrator as ig
from analysis.simulate import variational as va
from analysis.simulate.segments import checked_segments
from analysis.simulate.simulation import check_step_settings

STATE_COLUMNS = ("theta0", "theta_dot0")
# entries that are flags or follow another entry: no derivative of their own
NOT_DIFFERENTIABLE = frozenset({"BARRIER", "SIN_THETA_B", "SIZE"})


@dataclass(frozen=True)
class SensitivitySettings:
    """What to differentiate and how accurately to run: ``parameters`` names entries of the
    packed vector (``P`` member names such as "K", "MU0", "THETA_B", "A1"), the columns after
    the initial state's two; the integrator's tolerances and its step budget.  Refused with
    ValueError, naming the setting, when unknown or not honourable."""

    parameters: tuple[str, ...] = ()
    rtol: float = 1e-9
    atol: float = 1e-11
    max_steps: int = ig.DEFAULT_MAX_STEPS

    def __post_init__(self) -> None:
        check_step_settings(self.rtol, self.atol)
        if isinstance(self.parameters, str):
            raise ValueError(f"parameters = {self.parameters!r}: expected a tuple of names")
        known = sorted(name for name in P.__members__ if name not in NOT_DIFFERENTIABLE)
        for name in self.parameters:
            if name not in known:
                raise ValueError(f"parameters: {name!r} is not a packed entry; choose from "
                                 f"{', '.join(known)}")
        if len(set(self.parameters)) != len(self.parameters):
            raise ValueError(f"parameters = {self.parameters!r}: a name is repeated")
        if not (isinstance(self.max_steps, int) and self.max_steps > 0):
            raise ValueError(f"max_steps = {self.max_steps!r}: must be a positive integer")

    @property
    def columns(self) -> tuple[str, ...]:
        """The names of the Jacobian's columns: the initial state's, then the parameters."""
        return STATE_COLUMNS + tuple(self.parameters)


DEFAULT_SENSITIVITY_SETTINGS = SensitivitySettings()


@dataclass(frozen=True)
class Sensitivities:
    """A run sampled at ``t`` with its derivatives: ``jacobian[i, 0, j]`` is d theta(t[i]) /
    d column j, ``jacobian[i, 1, j]`` the same of theta' (columns named by ``columns``).
    Times the run did not reach (``status`` not "ok") are NaN; ``n_steps`` is the plain
    run's accepted steps, ``n_contacts`` its contact events that ended."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    jacobian: np.ndarray
    columns: tuple[str, ...]
    status: str
    n_steps: int
    n_contacts: int


def _refuse_friction(p: np.ndarray) -> None:
    if p[P.COULOMB_ACC] > 0.0:
        raise ValueError("sensitivities through Coulomb friction (COULOMB_ACC > 0) are not "
                         "supported: its stick and slip events have no saltation here yet")


def simulate_sensitivities(
    p: np.ndarray,
    theta0: float,
    theta_dot0: float,
    t: np.ndarray,
    *,
    t0: float = 0.0,
    settings: SensitivitySettings = DEFAULT_SENSITIVITY_SETTINGS,
) -> Sensitivities:
    """Run the packed vector ``p`` from (theta0, theta_dot0) at ``t0``, sampled at ``t``
    (increasing, not before ``t0``; the run ends at the last), with the derivatives of the
    samples as ``settings`` ask."""
    p = np.ascontiguousarray(p, dtype=float)
    if p.shape != (P.SIZE,):
        raise ValueError(f"packed vector has shape {p.shape}; expected ({int(P.SIZE)},)")
    _refuse_friction(p)
    if not all(math.isfinite(x) for x in (t0, theta0, theta_dot0)):
        raise ValueError(f"start ({t0!r}, {theta0!r}, {theta_dot0!r}) must be finite")
    out_t = np.ascontiguousarray(t, dtype=float)
    if out_t.ndim != 1 or out_t.size == 0:
        raise ValueError(f"t has shape {out_t.shape}; expected a non-empty 1-d array")
    if not (np.all(np.isfinite(out_t)) and np.all(np.diff(out_t) >= 0.0) and out_t[0] >= t0):
        raise ValueError("t must be finite, increasing and not before t0")
    columns = np.array([int(P[name]) for name in settings.parameters], dtype=np.int64)
    state = ig.new_state(float(t0), float(theta0), float(theta_dot0), p)
    contact0 = bool(state[ig.S_CONTACT] != 0.0)
    slide0 = float(state[ig.S_SLIDE])
    theta = np.empty(out_t.size)
    theta_dot = np.empty(out_t.size)
    control = ig.StepControl(settings.rtol, settings.atol, max_steps=settings.max_steps)
    run = ig.Run(p, state, control, dense_columns=va.REC_SIZE)
    written = run.advance(out_t, theta, theta_dot, float(out_t[-1]))
    jacobian = np.full((out_t.size, 2, 2 + columns.size), math.nan)
    va.propagate(p, columns, float(t0), float(theta0), float(theta_dot0), contact0, slide0,
                 run.dense, run.n_dense, out_t, written, jacobian)
    contacts = run.events[: run.n_events]
    return Sensitivities(
        t=out_t,
        theta=theta,
        theta_dot=theta_dot,
        jacobian=jacobian,
        columns=settings.columns,
        status=ig.STATUS_NAMES[int(state[ig.S_STATUS])],
        n_steps=int(state[ig.S_STEPS]),
        n_contacts=int(np.count_nonzero(contacts[:, ig.EV_KIND] == ig.KIND_CONTACT)),
    )


def segment_sensitivities(
    p: np.ndarray,
    t0: np.ndarray,
    state0: np.ndarray,
    out_t: np.ndarray,
    bounds: np.ndarray,
    *,
    settings: SensitivitySettings = DEFAULT_SENSITIVITY_SETTINGS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The segments of a multiple-shooting fit, as
    :func:`analysis.simulate.segments.integrate_segments` runs them, with their
    sensitivities: segment k from (t0[k], state0[k]) sampled at out_t[bounds[k]:bounds[k+1]]
    (its last time is its end).  Returns
    theta, theta' (NaN where a run stopped early), the Jacobian (times, 2, columns; a
    segment's columns 0 and 1 are its own start state's) and each segment's status code."""
    p, t0, state0, out_t, bounds = checked_segments(p, t0, state0, out_t, bounds)
    _refuse_friction(p)
    columns = np.array([int(P[name]) for name in settings.parameters], dtype=np.int64)
    theta = np.empty(out_t.size)
    theta_dot = np.empty(out_t.size)
    jacobian = np.full((out_t.size, 2, 2 + columns.size), math.nan)
    status = np.zeros(t0.size, dtype=np.int64)
    control = ig.StepControl(settings.rtol, settings.atol, max_steps=settings.max_steps)
    run = ig.Run(p, np.empty(0), control, dense_columns=va.REC_SIZE)
    for k in range(t0.size):
        a, b = int(bounds[k]), int(bounds[k + 1])
        start, th0, om0 = float(t0[k]), float(state0[k, 0]), float(state0[k, 1])
        # each segment from its own start, its rows from the (reused) buffers' start
        run.state = state = ig.new_state(start, th0, om0, p)
        run.n_events = run.n_dense = 0
        contact0 = bool(state[ig.S_CONTACT] != 0.0)
        slide0 = float(state[ig.S_SLIDE])
        written = run.advance(out_t[a:b], theta[a:b], theta_dot[a:b], float(out_t[b - 1]))
        va.propagate(p, columns, start, th0, om0, contact0, slide0, run.dense, run.n_dense,
                     out_t[a:b], written, jacobian[a:b])
        status[k] = int(state[ig.S_STATUS])
    return theta, theta_dot, jacobian, status
