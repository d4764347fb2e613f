"""Reference simulator of the impact pendulum, written from docs/MODEL.md alone on scipy's DOP853.

An oracle for tests and benchmarks: it shares no code with the project's integrator
(``analysis.simulate``) or its virtual rig, so an error in either cannot cancel against
it.  Integration is piecewise: wherever the right-hand side stops being smooth (contact
entry and exit, the no-adhesion clamp of the contact force, Coulomb friction's stick,
slip and reversal) a terminal event ends one ``solve_ivp`` run and the next starts from
the event state.  Clarity comes before speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

# How far one solve_ivp step may reach, as a fraction of the shortest period in play.
# Events are found by sign changes at step ends, so the cap keeps a swing's events from
# being stepped over; a graze shallower than a step can see is still integrated (every
# mode's right-hand side carries the contact force), only not located.
MAX_STEP_FRACTION = 1.0 / 10.0
# Pieces that end where they began; more in a row than this means the event logic is stuck.
MAX_EMPTY_PIECES = 20
# How far past 0 theta' must go before a reversal is found: far below any speed that shows,
# far above rounding (it moves the reversal by about 1e-12 s).
REVERSAL_OFFSET_RAD_S = 1e-10


class OverTheTopError(ValueError):
    """The pendulum reached the horizontal (cos theta <= 0): it left the experiment's regime."""


@dataclass(frozen=True)
class Pendulum:
    """The physical truth of docs/MODEL.md section 2 with the dynamics causes of section 6.

    ``K_n`` is the contact stiffness in N/m^n (Hertz: n = 1.5, K = (4/3) E sqrt(R));
    ``c_N_s_per_m`` adds Kelvin-Voigt contact damping, ``Tc_N_m`` pivot dry friction with
    stiction, ``c2_per_rad`` aerodynamic drag; ``barrier=False`` removes the barrier.
    Two effects outside the named causes (for tests of what the analysis cannot name):
    ``c3_per_s2`` a cubic restoring term c3 theta^3 in theta'' (a hairspring at the pivot),
    ``K_drift_per_s`` a contact stiffness K_n (1 + K_drift_per_s t) that drifts in time (a
    barrier warming up).  More of them, for decays: ``d3_s_per_rad2`` a cubic rate damping
    d3 theta'^3 in theta'', ``d21_per_rad2_s`` a position-dependent damping d21 theta^2
    theta' in theta''; ``damping_exponent`` p puts the contact damping on another power
    of the penetration, Fc = K_n delta^n + K_n mu0 delta^p deltadot (None: p = n, the
    Hunt-Crossley law); ``k_mount_N_per_m`` mounts the barrier on a spring k in series with
    the contact (0: a rigid mount): the elastic force F solves
    delta = (F / K_n)^(1/n) + F / k, and Fc = F (1 + mu0 deltadot) + c deltadot with
    delta the total penetration.
    """

    m_kg: float
    l_m: float
    L_m: float
    zeta: float
    K_n: float
    mu0_s_per_m: float
    g_m_s2: float = 9.81
    n: float = 1.5
    c_N_s_per_m: float = 0.0
    theta_b_rad: float = 0.0
    Tc_N_m: float = 0.0
    c2_per_rad: float = 0.0
    barrier: bool = True
    c3_per_s2: float = 0.0
    K_drift_per_s: float = 0.0
    d3_s_per_rad2: float = 0.0
    d21_per_rad2_s: float = 0.0
    damping_exponent: float | None = None
    k_mount_N_per_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("m_kg", "l_m", "L_m", "g_m_s2", "K_n", "n"):
            _require_finite(name, getattr(self, name), lower=0.0, strict=True)
        for name in ("zeta", "mu0_s_per_m", "c_N_s_per_m", "Tc_N_m", "c2_per_rad",
                     "d3_s_per_rad2", "d21_per_rad2_s", "k_mount_N_per_m"):
            _require_finite(name, getattr(self, name), lower=0.0, strict=False)
        for name in ("theta_b_rad", "c3_per_s2", "K_drift_per_s"):
            _require_finite(name, getattr(self, name), lower=-math.inf, strict=False)
        if self.damping_exponent is not None:
            _require_finite("damping_exponent", self.damping_exponent, lower=0.0, strict=True)
        if self.damping_exponent is not None and (self.k_mount_N_per_m > 0.0
                                                  or self.c_N_s_per_m > 0.0):
            raise ValueError("another damping exponent replaces the Hunt-Crossley damping "
                             "alone: no compliant mount, no viscous contact damping with it")
        if abs(self.theta_b_rad) >= math.pi / 2:
            raise ValueError(
                f"theta_b_rad = {self.theta_b_rad!r}: the barrier must sit below the pivot "
                "(|theta_b_rad| < pi/2)"
            )

    @property
    def omega_rad_s(self) -> float:
        """Small-angle natural frequency sqrt(g / L)."""
        return math.sqrt(self.g_m_s2 / self.L_m)


@dataclass(frozen=True)
class TableMotion:
    """x_t(t) = A g(t) (sin(phase) + h2 sin(2 phase + phi2)), phase = 2 pi f t + phase_rad.

    ``phase_rad`` is the drive phase at t = 0; amplitude 0 leaves the table at rest.  The
    gain g(t) = 1 + am_depth sin(2 pi am_frequency_hz t + am_phase_rad) is 1 unless an
    amplifier's wandering gain is modelled (an effect outside the named causes).
    """

    amplitude_m: float = 0.0
    frequency_hz: float = 0.0
    phase_rad: float = 0.0
    h2: float = 0.0
    phi2_rad: float = 0.0
    am_depth: float = 0.0
    am_frequency_hz: float = 0.0
    am_phase_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("amplitude_m", "frequency_hz", "h2", "am_depth", "am_frequency_hz"):
            _require_finite(name, getattr(self, name), lower=0.0, strict=False)
        if self.am_depth >= 1.0:
            raise ValueError(f"am_depth = {self.am_depth!r}: must be below 1")
        for name in ("phase_rad", "phi2_rad", "am_phase_rad"):
            _require_finite(name, getattr(self, name), lower=-math.inf, strict=False)
        if self.amplitude_m > 0 and self.frequency_hz <= 0:
            raise ValueError(
                f"frequency_hz = {self.frequency_hz!r}: a table moving with amplitude "
                f"{self.amplitude_m} m needs a positive frequency"
            )

    @property
    def is_moving(self) -> bool:
        """True when the table is driven."""
        return self.amplitude_m > 0

    @property
    def period_s(self) -> float:
        """Drive period 1/f (inf for a table at rest)."""
        return 1.0 / self.frequency_hz if self.is_moving else math.inf

    def phase(self, t: float | np.ndarray) -> float | np.ndarray:
        """Drive phase 2 pi f t + phase_rad (not wrapped)."""
        return 2.0 * math.pi * self.frequency_hz * np.asarray(t) + self.phase_rad

    def displacement(self, t: float | np.ndarray) -> float | np.ndarray:
        """Table displacement x_t(t) [m]."""
        phase = self.phase(t)
        gain = 1.0 + self.am_depth * np.sin(
            2.0 * math.pi * self.am_frequency_hz * np.asarray(t) + self.am_phase_rad)
        return self.amplitude_m * gain * (
            np.sin(phase) + self.h2 * np.sin(2.0 * phase + self.phi2_rad))

    def acceleration(self, t: float) -> float:
        """Table acceleration x_t''(t) [m/s^2] at one instant (the gain's derivatives
        included)."""
        if not self.is_moving:
            return 0.0
        w = 2.0 * math.pi * self.frequency_hz
        phase = w * t + self.phase_rad
        if self.am_depth == 0.0:  # a steady gain (kept in this order: records stay bitwise)
            return -w * w * self.amplitude_m * (
                math.sin(phase) + 4.0 * self.h2 * math.sin(2.0 * phase + self.phi2_rad)
            )
        second = 2.0 * phase + self.phi2_rad
        shape = math.sin(phase) + self.h2 * math.sin(second)
        shape_rate = w * (math.cos(phase) + 2.0 * self.h2 * math.cos(second))
        shape_acc = -w * w * (math.sin(phase) + 4.0 * self.h2 * math.sin(second))
        wm = 2.0 * math.pi * self.am_frequency_hz
        psi = wm * t + self.am_phase_rad
        gain = 1.0 + self.am_depth * math.sin(psi)
        gain_rate = self.am_depth * wm * math.cos(psi)
        gain_acc = -self.am_depth * wm * wm * math.sin(psi)
        return self.amplitude_m * (gain_acc * shape + 2.0 * gain_rate * shape_rate
                                   + gain * shape_acc)


@dataclass(frozen=True)
class Event:
    """One terminal event: its time, kind and the state (theta, theta') there.

    Kinds: contact_entry, contact_exit, clamp (the force would turn adhesive), unclamp,
    stick, slip (stick ends), reversal (theta' = 0 without sticking).
    """

    t_s: float
    kind: str
    theta_rad: float
    theta_dot_rad_s: float


@dataclass(frozen=True)
class ReferenceRun:
    """Samples at the requested times, every event, and the final state."""

    t_s: np.ndarray
    theta_rad: np.ndarray
    theta_dot_rad_s: np.ndarray
    lowpass_rad: np.ndarray | None
    events: tuple[Event, ...]
    final_t_s: float
    final_state: np.ndarray = field(repr=False)

    def events_of(self, kind: str) -> list[Event]:
        """The events of one kind, in time order."""
        return [event for event in self.events if event.kind == kind]


@dataclass
class _Mode:
    """Which side of each non-smooth surface the motion is on; sets event directions."""

    in_contact: bool
    clamped: bool
    direction: float  # sign of theta' for the friction term (+1 or -1)
    stuck: bool


class _Equations:
    """The terms of the equation of motion for one pendulum and table."""

    def __init__(self, pendulum: Pendulum, table: TableMotion, lowpass_tau_s: float | None):
        self.p = pendulum
        self.table = table
        self.omega2 = pendulum.g_m_s2 / pendulum.L_m
        self.two_zeta_omega = 2.0 * pendulum.zeta * pendulum.omega_rad_s
        self.contact_gain = pendulum.l_m / (pendulum.m_kg * pendulum.L_m**2)
        self.friction_acc = pendulum.Tc_N_m / (pendulum.m_kg * pendulum.L_m**2)
        self.sin_b = math.sin(pendulum.theta_b_rad)
        self.lowpass_tau_s = lowpass_tau_s
        self.acceleration_without_friction = self._acceleration_without_friction()

    def surface(self, theta: float) -> float:
        """sin(theta) - sin(theta_b): the penetration over l, > 0 in contact."""
        return math.sin(theta) - self.sin_b

    def stiffness(self, t: float) -> float:
        """K_n at time t (drifting when K_drift_per_s is not 0)."""
        return self.p.K_n * (1.0 + self.p.K_drift_per_s * t)

    def elastic_force(self, t: float, delta: float) -> float:
        """The contact's elastic force at penetration ``delta`` > 0 [N]: K_n delta^n, or with
        a compliant mount the F that solves delta = (F / K_n)^(1/n) + F / k."""
        p = self.p
        stiffness = self.stiffness(t)
        rigid = stiffness * delta**p.n
        if p.k_mount_N_per_m == 0.0:
            return rigid
        mount = p.k_mount_N_per_m * delta
        high = min(rigid, mount)  # in series, softer than either alone

        def excess(force: float) -> float:
            return (force / stiffness) ** (1.0 / p.n) + force / p.k_mount_N_per_m - delta

        if high <= 0.0 or excess(high) <= 0.0:
            return high
        return brentq(excess, 0.0, high, xtol=1e-15 * max(high, 1e-300), rtol=1e-14)

    def unclamped_force(self, t: float, theta: float, theta_dot: float) -> float:
        """K_n delta^n (1 + mu0 deltadot) + c deltadot in contact (K_n delta^n + K_n mu0
        delta^p deltadot with another damping exponent p; the mount's series
        force in place of K_n delta^n with a compliant mount), else 0 [N]."""
        p = self.p
        delta = p.l_m * self.surface(theta)
        if not p.barrier or delta <= 0.0 or math.cos(theta) <= 0.0:
            return 0.0
        delta_dot = p.l_m * math.cos(theta) * theta_dot
        if p.damping_exponent is not None:
            stiffness = self.stiffness(t)
            return (stiffness * delta**p.n
                    + stiffness * p.mu0_s_per_m * delta**p.damping_exponent * delta_dot)
        return (self.elastic_force(t, delta) * (1.0 + p.mu0_s_per_m * delta_dot)
                + p.c_N_s_per_m * delta_dot)

    def clamp_indicator(self, t: float, theta: float, theta_dot: float) -> float:
        """A smooth function with the sign of the unclamped force inside the contact.

        Pure Hunt-Crossley's force has the sign of 1 + mu0 deltadot, which stays away from 0
        at contact entry where the force itself starts at 0.  With viscous damping the
        force law itself is used, continued past the exit (delta < 0 counts as 0) so that
        a step reaching beyond the exit cannot read a spurious zero.
        With another damping exponent p the force over delta^min(n, p) is used: it has the
        force's sign and, at entry, that of deltadot (p < n) or 1 (p > n).
        """
        p = self.p
        delta_dot = p.l_m * math.cos(theta) * theta_dot
        if p.damping_exponent is not None and p.damping_exponent != p.n:
            delta = max(p.l_m * self.surface(theta), 0.0)
            low = min(p.n, p.damping_exponent)
            return delta ** (p.n - low) + p.mu0_s_per_m * delta ** (
                p.damping_exponent - low) * delta_dot
        if p.c_N_s_per_m == 0.0:
            return 1.0 + p.mu0_s_per_m * delta_dot
        delta = max(p.l_m * self.surface(theta), 0.0)
        force = self.elastic_force(t, delta) if delta > 0.0 else 0.0
        return force * (1.0 + p.mu0_s_per_m * delta_dot) + p.c_N_s_per_m * delta_dot

    def _acceleration_without_friction(self) -> Callable[[float, float, float], float]:
        """theta''(t, theta, theta') from every term except Coulomb friction.

        The right-hand side's cost is the reference's: the terms are read once into the
        closure, and the plain contact law (no other damping exponent, no mount) and the
        steady table are written out here; the other laws call :meth:`unclamped_force` and
        :meth:`TableMotion.acceleration`.  Every operation is the same IEEE operation in
        the same order as in those methods: the motion is the same to the last bit."""
        p, table = self.p, self.table
        c3, d3, d21, c2 = p.c3_per_s2, p.d3_s_per_rad2, p.d21_per_rad2_s, p.c2_per_rad
        two_zeta_omega, omega2, contact_gain = self.two_zeta_omega, self.omega2, self.contact_gain
        L, l_m, sin_b, barrier = p.L_m, p.l_m, self.sin_b, p.barrier
        plain_contact = p.damping_exponent is None and p.k_mount_N_per_m == 0.0
        K_n, K_drift, n, mu0, c = p.K_n, p.K_drift_per_s, p.n, p.mu0_s_per_m, p.c_N_s_per_m
        moving, steady = table.is_moving, table.am_depth == 0.0
        w = 2.0 * math.pi * table.frequency_hz
        amplitude, phase0, h2, phi2 = table.amplitude_m, table.phase_rad, table.h2, table.phi2_rad
        table_acceleration, unclamped_force = table.acceleration, self.unclamped_force
        sin, cos = math.sin, math.cos

        def acceleration(t: float, theta: float, theta_dot: float) -> float:
            sin_theta, cos_theta = sin(theta), cos(theta)
            delta = l_m * (sin_theta - sin_b)
            if not barrier or delta <= 0.0 or cos_theta <= 0.0:
                force = 0.0
            elif plain_contact:
                delta_dot = l_m * cos_theta * theta_dot
                force = max((K_n * (1.0 + K_drift * t)) * delta**n * (1.0 + mu0 * delta_dot)
                            + c * delta_dot, 0.0)
            else:
                force = max(unclamped_force(t, theta, theta_dot), 0.0)
            if not moving:
                table_acc = 0.0
            elif steady:
                phase = w * t + phase0
                table_acc = -w * w * amplitude * (sin(phase) + 4.0 * h2 * sin(2.0 * phase + phi2))
            else:
                table_acc = table_acceleration(t)
            return (
                -c3 * theta**3
                - two_zeta_omega * theta_dot
                - d3 * theta_dot**3
                - d21 * theta**2 * theta_dot
                - c2 * theta_dot * abs(theta_dot)
                - table_acc / L * cos_theta
                - omega2 * sin_theta
                - contact_gain * force
            )

        return acceleration

    def rhs(self, mode: _Mode) -> Callable[[float, np.ndarray], list[float]]:
        """d/dt of (theta, theta'[, low-passed theta]) in one mode."""
        friction = self.friction_acc * mode.direction
        tau = self.lowpass_tau_s
        acceleration = self.acceleration_without_friction

        def sliding(t: float, y: np.ndarray) -> list[float]:
            # Python floats, not numpy scalars: the same IEEE operations in the same order
            # (bit for bit the same motion), each several times cheaper
            if tau is None:
                theta, theta_dot = y.tolist()
                return [theta_dot, acceleration(float(t), theta, theta_dot) - friction]
            theta, theta_dot, low = y.tolist()
            return [theta_dot, acceleration(float(t), theta, theta_dot) - friction,
                    (theta - low) / tau]

        def stuck(t: float, y: np.ndarray) -> list[float]:
            if tau is None:
                return [0.0, 0.0]
            return [0.0, 0.0, (y[0] - y[2]) / tau]

        return stuck if mode.stuck else sliding


def _terminal(function: Callable[[float, np.ndarray], float], direction: float):
    function.terminal = True
    function.direction = direction
    return function


def simulate_reference(
    pendulum: Pendulum,
    table: TableMotion,
    theta0_rad: float,
    theta_dot0_rad_s: float,
    t_eval_s: np.ndarray,
    *,
    t_start_s: float = 0.0,
    t_end_s: float | None = None,
    lowpass_tau_s: float | None = None,
    lowpass0_rad: float | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
) -> ReferenceRun:
    """Integrate from (theta0, theta'0) at ``t_start_s`` to ``t_end_s`` (default: the last
    sample time), sampling the dense output at ``t_eval_s`` (increasing, within the span).

    ``lowpass_tau_s`` adds a continuous first-order low pass of theta as a third state
    (an analog filter on the angle), starting from ``lowpass0_rad`` (default theta0).
    Raises OverTheTopError when the pendulum reaches the horizontal.
    """
    t_eval = np.asarray(t_eval_s, dtype=float)
    t_end = _checked_span(t_eval, t_start_s, t_end_s)
    _check_start(theta0_rad, theta_dot0_rad_s, lowpass_tau_s)

    equations = _Equations(pendulum, table, lowpass_tau_s)
    state = [float(theta0_rad), float(theta_dot0_rad_s)]
    if lowpass_tau_s is not None:
        state.append(float(theta0_rad if lowpass0_rad is None else lowpass0_rad))
    y = np.array(state)
    mode = _initial_mode(equations, t_start_s, y)
    if mode.stuck:
        y[1] = 0.0
    max_step = MAX_STEP_FRACTION * min(table.period_s, 2.0 * math.pi / pendulum.omega_rad_s)
    # the end of the span is sampled too: it gives the final state
    times = t_eval if t_eval.size and t_eval[-1] == t_end else np.append(t_eval, t_end)

    samples = np.empty((y.size, times.size))
    filled = 0
    events: list[Event] = []
    t = float(t_start_s)
    empty_pieces = 0
    while filled < times.size:
        piece_events, handlers = _piece_events(equations, mode)
        solution = solve_ivp(
            equations.rhs(mode),
            (t, t_end),
            y,
            method="DOP853",
            t_eval=times[filled:],
            events=piece_events,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
        )
        if solution.status < 0:
            raise RuntimeError(f"solve_ivp failed after t = {t}: {solution.message}")
        count = len(solution.t)  # solve_ivp gives a list when no sample fell in the piece
        if count:
            samples[:, filled:filled + count] = solution.y
        filled += count
        if solution.status == 0:
            break
        t_event = max(found[-1] for found in solution.t_events if len(found))
        empty_pieces = empty_pieces + 1 if t_event == t else 0
        if empty_pieces > MAX_EMPTY_PIECES:
            raise RuntimeError(f"event logic makes no progress at t = {t_event} ({mode})")
        t = float(t_event)
        y = _handle_events(solution, t_event, handlers, mode, events, y)
        if mode.stuck:
            y[1] = 0.0
    if filled != times.size:
        raise RuntimeError(f"sampled {filled} of {times.size} requested times")
    return ReferenceRun(
        t_s=t_eval,
        theta_rad=samples[0, : t_eval.size],
        theta_dot_rad_s=samples[1, : t_eval.size],
        lowpass_rad=samples[2, : t_eval.size] if lowpass_tau_s is not None else None,
        events=tuple(events),
        final_t_s=t_end,
        final_state=samples[:, -1].copy(),
    )


def _checked_span(t_eval: np.ndarray, t_start_s: float, t_end_s: float | None) -> float:
    """The end of the span; ValueError unless the sample times increase within it."""
    if t_eval.ndim != 1:
        raise ValueError(f"t_eval_s has shape {t_eval.shape}; expected a 1-d array")
    t_end = float(t_eval[-1]) if t_end_s is None else float(t_end_s)
    if not (math.isfinite(t_start_s) and math.isfinite(t_end) and t_end > t_start_s):
        raise ValueError(f"time span ({t_start_s!r}, {t_end!r}): expected finite, start < end")
    if t_eval.size and (
        np.any(np.diff(t_eval) <= 0) or t_eval[0] < t_start_s or t_eval[-1] > t_end
    ):
        raise ValueError(
            f"t_eval_s must increase strictly within [{t_start_s}, {t_end}]; "
            f"it spans [{t_eval[0]}, {t_eval[-1]}]"
        )
    return t_end


def _check_start(
    theta0_rad: float, theta_dot0_rad_s: float, lowpass_tau_s: float | None
) -> None:
    """ValueError for a non-finite start or filter constant; OverTheTopError above horizontal."""
    if lowpass_tau_s is not None:
        _require_finite("lowpass_tau_s", lowpass_tau_s, lower=0.0, strict=True)
    for name, value in (("theta0_rad", theta0_rad), ("theta_dot0_rad_s", theta_dot0_rad_s)):
        _require_finite(name, value, lower=-math.inf, strict=False)
    if math.cos(theta0_rad) <= 0.0:
        raise OverTheTopError(f"theta0_rad = {theta0_rad!r} is at or above the horizontal")


def _handle_events(
    solution: Any, t_event: float, handlers: list, mode: _Mode, events: list[Event],
    y: np.ndarray,
) -> np.ndarray:
    """Apply the events that ended a piece at ``t_event`` to the mode and log them; the state
    to restart from (``y`` when none of them fired there)."""
    t = float(t_event)
    for index, found in enumerate(solution.t_events):
        if len(found) and found[-1] == t_event:
            y = np.array(solution.y_events[index][-1], dtype=float)
            kind = handlers[index](t, y, mode)
            events.append(Event(t, kind, float(y[0]), float(y[1])))
    return y


def _initial_mode(equations: _Equations, t: float, y: np.ndarray) -> _Mode:
    """The mode of a state that is not on an event surface (or is at rest: may stick)."""
    theta, theta_dot = float(y[0]), float(y[1])
    in_contact = equations.p.barrier and equations.surface(theta) > 0.0
    clamped = in_contact and equations.clamp_indicator(t, theta, theta_dot) < 0.0
    mode = _Mode(in_contact=in_contact, clamped=clamped, direction=1.0, stuck=False)
    if equations.friction_acc > 0.0:
        if theta_dot != 0.0:
            mode.direction = math.copysign(1.0, theta_dot)
        else:
            _stick_or_slide(equations, t, theta, mode)
    return mode


def _stick_or_slide(equations: _Equations, t: float, theta: float, mode: _Mode) -> str:
    """At theta' = 0: stick while the other torques stay within Tc, else slide their way."""
    other = equations.acceleration_without_friction(t, theta, 0.0)
    if abs(other) <= equations.friction_acc:
        mode.stuck = True
        return "stick"
    mode.stuck = False
    mode.direction = math.copysign(1.0, other)
    return "reversal"


def _piece_events(equations: _Equations, mode: _Mode):
    """The terminal event functions of one mode and, for each, what it does to the mode."""
    pairs = [_over_the_top_event()]
    if equations.p.barrier:
        pairs.append(_surface_event(equations, mode))
    if mode.in_contact and not mode.stuck:
        pairs.append(_clamp_event(equations, mode))
    if equations.friction_acc > 0.0:
        pairs += _slip_events(equations) if mode.stuck else [_reversal_event(equations, mode)]
    return [function for function, _ in pairs], [handler for _, handler in pairs]


def _over_the_top_event():
    """Reaching the horizontal: refused, outside the experiment's regime."""

    def over_the_top(t: float, y: np.ndarray) -> float:
        return math.cos(y[0])

    def refuse_over_the_top(t: float, y: np.ndarray, mode: _Mode) -> str:
        raise OverTheTopError(
            f"the pendulum reached the horizontal at t = {t:.6f} s (theta = {y[0]:.4f} rad): "
            "driven over the top, outside the experiment's regime"
        )

    return _terminal(over_the_top, -1.0), refuse_over_the_top


def _surface_event(equations: _Equations, mode: _Mode):
    """Crossing the barrier's surface: contact entry or exit."""

    def surface(t: float, y: np.ndarray) -> float:
        return equations.surface(y[0])

    def cross_surface(t: float, y: np.ndarray, mode: _Mode) -> str:
        mode.in_contact = not mode.in_contact
        mode.clamped = False  # the force starts from 0 and grows at entry; 0 after exit
        return "contact_entry" if mode.in_contact else "contact_exit"

    # after entry only an exit can come next, and vice versa: a restart that lands a
    # rounding error on the wrong side cannot fire the same crossing again
    return _terminal(surface, -1.0 if mode.in_contact else 1.0), cross_surface


def _clamp_event(equations: _Equations, mode: _Mode):
    """In contact: the contact force reaching zero (clamp) or leaving it (unclamp)."""

    def clamp(t: float, y: np.ndarray) -> float:
        return equations.clamp_indicator(t, y[0], y[1])

    def toggle_clamp(t: float, y: np.ndarray, mode: _Mode) -> str:
        mode.clamped = not mode.clamped
        return "clamp" if mode.clamped else "unclamp"

    return _terminal(clamp, 1.0 if mode.clamped else -1.0), toggle_clamp


def _slip_events(equations: _Equations) -> list:
    """Stuck: the other torques exceeding friction forward or backward start a slide."""

    def slip_forward(t: float, y: np.ndarray) -> float:
        other = equations.acceleration_without_friction(t, y[0], 0.0)
        return other - equations.friction_acc

    def slip_backward(t: float, y: np.ndarray) -> float:
        other = equations.acceleration_without_friction(t, y[0], 0.0)
        return other + equations.friction_acc

    def slip(direction: float):
        def start_sliding(t: float, y: np.ndarray, mode: _Mode) -> str:
            mode.stuck = False
            mode.direction = direction
            return "slip"

        return start_sliding

    return [(_terminal(slip_forward, 1.0), slip(1.0)), (_terminal(slip_backward, -1.0), slip(-1.0))]


def _reversal_event(equations: _Equations, mode: _Mode):
    """Sliding: theta' reaching zero, where the pendulum sticks or slides back."""
    direction = mode.direction

    def speed(t: float, y: np.ndarray) -> float:
        # A piece that starts from a reversal starts at theta' = 0, a root the event
        # search would return at once when theta' comes back through 0 within the
        # first step (a fast drive turning it round): offset so that the start lies
        # on the side the motion leaves, and the crossing is the one ahead.
        return y[1] + REVERSAL_OFFSET_RAD_S * direction

    def speed_zero(t: float, y: np.ndarray, mode: _Mode) -> str:
        y[1] = 0.0
        return _stick_or_slide(equations, t, float(y[0]), mode)

    return _terminal(speed, -mode.direction), speed_zero


def _require_finite(name: str, value: float, *, lower: float, strict: bool) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{name} = {value!r}: expected a number")
    if not math.isfinite(value) or value < lower or (strict and value == lower):
        bound = f"> {lower}" if strict else f">= {lower}"
        raise ValueError(f"{name} = {value!r}: expected a finite number {bound}")
