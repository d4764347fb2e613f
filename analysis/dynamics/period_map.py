"""The stroboscopic map of a forced model, with one model parameter free: images and Jacobians.

P^k(x; value) is the state (theta, theta') after ``periods`` = k drive periods from drive
phase 0 (t = 0) in state x, for the model with the named parameter set to ``value``.  Its
trajectory is the project's compiled integrator with its exact contact events
(:func:`analysis.simulate.segments.integrate_segments`: all the runs a Jacobian needs go
in one compiled call).

Jacobians come by default (``jacobians="sensitivities"``) from one run of the forward
sensitivities (:func:`analysis.simulate.sensitivity.simulate_sensitivities`): the
variational equations carried along the run's own steps and through every contact with the
saltation matrix of the event, so d P / d x and d P / d value are the derivatives of the
integrator's own discrete map, one run per (state, value).  d P / d value is the chain
rule through the packed vector: the sensitivities to the entries the parameter moves
times their derivatives with respect to it (the packing is algebraic: central
differences of it, exact to rounding where the packing is linear), plus the vector field
at the image times d T / d value when the parameter moves the drive's period T.  The
sensitivities do not support Coulomb friction: with it the map falls back to the
differences below (``jacobian_method`` says which is used, ``jacobian_note`` why).
The sensitivities are the derivatives of the integrator's steps, not of its choice of
them, and the step control watches the state, not its derivatives: at the same tolerance
they are less accurate than Richardson's differences of runs (measured on the 10 Hz
period-2 orbit at its period-doubling, against both routes at rtol 1e-13: det(J + I) off
by 5e-8 at rtol 1e-11, by 7e-9 at 1e-12, where the differences at 1e-11 are off by 2e-9).
With the sensitivities every run of the map (images, sensitivities, the sampled orbit)
is therefore made at ``SENSITIVITY_TOLERANCE_FACTOR`` times the tolerances asked for
(``run_rtol``, ``run_atol``): a period-doubling then lands within 3e-10 of where the
differences put it.

``jacobians="differences"`` takes central finite differences instead: the Hertzian (and
Kelvin-Voigt) contact force is continuous in the state, so the
flow, and the map, are continuously differentiable across contact entry and exit, and
differences of the map see every contact.  Each column steps the state by
``FD_RELATIVE_STEP`` times its size (floored at the typical size of a swing, so that a
state near zero is not stepped by a rounding error), the parameter by that fraction of the
larger of its value and its scale.  The integrator runs at rtol 1e-11 (``MAP_RTOL``), so
the map's rounding noise (about 1e-13 rad, measured) enters the columns at about 1e-8,
and the O(h^2) truncation error is of the same order (checked: steps from 1e-3 to 1e-7 of
the state agree to 1e-7 in the multipliers of case (g)'s orbits).  :func:`Linearisation`
carries a second route, Richardson's: the columns at steps h and 2 h give a fourth-order
Jacobian and an estimate of the plain one's error; tests compare both with a
least-squares fit to a ring of runs of the single-run simulator, and the sensitivities'
Jacobian with both.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from analysis.dynamics.model_parameters import model_with, parameter_value
from analysis.model import Model, acceleration
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate_packed
from analysis.simulate import integrator as ig
from analysis.simulate.result import ContactEvents
from analysis.simulate.segments import integrate_segments
from analysis.simulate.sensitivity import SensitivitySettings, simulate_sensitivities

MAP_RTOL = 1e-11
MAP_ATOL = 1e-13
FD_RELATIVE_STEP = 1e-5
ANGLE_FLOOR_RAD = 0.05  # the size a finite-difference step is a fraction of, at least
ORBIT_SAMPLES_PER_PERIOD = 512
JACOBIAN_METHODS = ("sensitivities", "differences")
SENSITIVITY_TOLERANCE_FACTOR = 0.1  # the map's runs with the sensitivities: rtol / 10
PACKING_RELATIVE_STEP = 1e-5  # differences of the (algebraic) packing
# packed entries that are flags or follow another entry (SIN_THETA_B follows THETA_B, whose
# sensitivity column carries it): no column of their own
_FOLLOWING = frozenset({int(P.SIN_THETA_B), int(P.BARRIER)})


class MapError(RuntimeError):
    """The map could not be evaluated: the integrator stopped (the pendulum went over the top,
    the step size underflowed) at the named parameter value and state."""


@dataclass(frozen=True)
class Linearisation:
    """The map at one (state, value): its image, Jacobian d P / d x and d P / d value.

    ``jacobian_error`` is Richardson's estimate of the Jacobian's error (largest entry,
    relative to the largest entry of J); 0 when the second step was not run and with the
    sensitivities (exact derivatives of the integrator's discrete map).
    """

    image: np.ndarray
    jacobian: np.ndarray
    parameter_derivative: np.ndarray
    jacobian_error: float = 0.0

    @cached_property
    def multipliers(self) -> np.ndarray:
        """Floquet multipliers: eigenvalues of the Jacobian, largest modulus first."""
        values = np.linalg.eigvals(self.jacobian).astype(complex)
        return values[np.argsort(-np.abs(values), kind="stable")]


@dataclass(frozen=True)
class OrbitSample:
    """One pass of k drive periods from a state (the second one: for a periodic orbit the
    same as the first), sampled densely, with the contacts that end in it.

    ``max_angle_rad`` is the largest angle (refined between samples by the cubic through
    the neighbouring samples' angles and rates), ``barrier_distance_rad`` = theta_b minus
    it (negative while the orbit is in contact), ``apex_distance_rad`` the same for the
    swing's apex (local maximum) nearest the barrier, free (> 0) or in contact (< 0): it
    passes through zero wherever a contact begins; ``impact_speed_rad_s`` the largest
    entry rate of a contact (0 without contact).
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    contacts: ContactEvents
    max_angle_rad: float
    barrier_distance_rad: float
    apex_distance_rad: float

    @property
    def impact_speed_rad_s(self) -> float:
        """Largest theta' at contact entry (0 when the orbit never touches the barrier)."""
        speeds = self.contacts.theta_dot_in
        return float(np.max(np.abs(speeds))) if speeds.size else 0.0


class PeriodMap:
    """P^k(x; value) of ``model`` with ``parameter`` free; see the module docstring.

    ``parameter_scale`` is the parameter's typical size (e.g. the range a continuation
    covers): the finite-difference step in the parameter never falls below a fraction
    of it.  ``jacobians`` is "sensitivities" (default) or "differences"; the first falls
    back to the second with Coulomb friction (``jacobian_method``, ``jacobian_note``).
    """

    def __init__(
        self,
        model: Model,
        parameter: str,
        periods: int = 1,
        *,
        parameter_scale: float | None = None,
        rtol: float = MAP_RTOL,
        atol: float = MAP_ATOL,
        jacobians: str = "sensitivities",
    ) -> None:
        if periods < 1:
            raise ValueError(f"periods = {periods}: a period map needs k >= 1")
        if jacobians not in JACOBIAN_METHODS:
            raise ValueError(f"jacobians = {jacobians!r}: choose from "
                             f"{', '.join(JACOBIAN_METHODS)}")
        self.jacobians = jacobians
        self.model = model
        self.parameter = parameter
        self.periods = int(periods)
        self.rtol = rtol
        self.atol = atol
        start = parameter_value(model, parameter)  # refuses an unknown name
        self.parameter_scale = float(parameter_scale or abs(start) or 1.0)
        self._packed_cache: tuple[float, np.ndarray] | None = None
        self._direction_cache: tuple[float | None, SensitivitySettings, np.ndarray,
                                     float] | None = None
        if model.drive.frequency_hz <= 0 or not model.drive.is_forced:
            raise ValueError(
                "a stroboscopic map needs a forced model (amplitude and frequency > 0)"
            )
        self.jacobian_method, self.jacobian_note = jacobians, "central differences"
        if jacobians == "sensitivities":
            self.jacobian_note = ("forward sensitivities (the variational equations through "
                                  "every contact)")
            if self.packed(start)[P.COULOMB_ACC] > 0.0 or self._moves_friction(start):
                self.jacobian_method = "differences"
                self.jacobian_note = ("central differences: the sensitivities do not "
                                      "support Coulomb friction")
        # the tolerances every run of the map is made at (see the module docstring)
        tighter = SENSITIVITY_TOLERANCE_FACTOR if self.jacobian_method == "sensitivities" else 1.0
        self.run_rtol, self.run_atol = rtol * tighter, atol * tighter

    def with_periods(self, periods: int) -> PeriodMap:
        """The same map iterated ``periods`` times per application."""
        return PeriodMap(
            self.model, self.parameter, periods, parameter_scale=self.parameter_scale,
            rtol=self.rtol, atol=self.atol, jacobians=self.jacobians,
        )

    def packed(self, value: float) -> np.ndarray:
        """The packed parameter vector at ``value`` (the last one is kept); MapError for a
        value outside the parameter's physical range."""
        if self._packed_cache is None or self._packed_cache[0] != value:
            try:
                model = model_with(self.model, self.parameter, value)
            except ValueError as error:  # a corrector's trial beyond the physical range
                raise MapError(str(error)) from None
            self._packed_cache = (value, model.pack())
        return self._packed_cache[1]

    def duration_s(self, value: float) -> float:
        """k drive periods at ``value`` [s]."""
        return self.periods * 2.0 * math.pi / self.packed(value)[P.OMEGA_DRIVE]

    def drive_rate(self, value: float) -> float:
        """Omega [rad/s] at ``value``: theta' / Omega is the rate per radian of drive phase."""
        return float(self.packed(value)[P.OMEGA_DRIVE])

    def images(self, value: float, states: np.ndarray) -> np.ndarray:
        """P^k of each row of ``states`` (n, 2) at ``value``; MapError when a run stops."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        p = self.packed(value)
        n = states.shape[0]
        end = np.full(n, self.duration_s(value))
        theta, rate, status = integrate_segments(
            p, np.zeros(n), states, end, np.arange(n + 1), rtol=self.run_rtol, atol=self.run_atol
        )
        failed = np.flatnonzero(status != ig.STATUS_OK)
        if failed.size:
            i = int(failed[0])
            raise MapError(
                f"the integrator stopped ({ig.STATUS_NAMES[int(status[i])]}) within "
                f"{self.periods} period(s) from (theta, theta') = ({states[i, 0]:.6g}, "
                f"{states[i, 1]:.6g}) at {self.parameter} = {value:.10g}"
            )
        return np.column_stack([theta, rate])

    def state_steps(self, state: np.ndarray, value: float) -> np.ndarray:
        """Finite-difference step of each state component (see the module docstring)."""
        floor = np.array([ANGLE_FLOOR_RAD, ANGLE_FLOOR_RAD * self.drive_rate(value)])
        return FD_RELATIVE_STEP * np.maximum(np.abs(state), floor)

    def parameter_step(self, value: float) -> float:
        """Finite-difference step of the parameter."""
        return FD_RELATIVE_STEP * max(abs(value), self.parameter_scale)

    def linearise(
        self, value: float, state: np.ndarray, *, richardson: bool = False
    ) -> Linearisation:
        """Image, Jacobian and parameter derivative at (state, value): from the
        sensitivities, or by central differences, where ``richardson`` adds the columns at
        twice the steps and returns the extrapolated (fourth-order) Jacobian and parameter
        derivative, with the plain Jacobian's error estimate (the sensitivities need no
        such check: ``richardson`` changes nothing there)."""
        state = np.asarray(state, dtype=float)
        if self.jacobian_method == "sensitivities":
            return self._sensitivity_linearisation(value, state)
        h = self.state_steps(state, value)
        scales = (1.0, 2.0) if richardson else (1.0,)
        runs = [state]
        for scale in scales:
            for j in range(2):
                step = np.zeros(2)
                step[j] = scale * h[j]
                runs += [state + step, state - step]
        out = self.images(value, np.array(runs))
        image = out[0]
        columns = []
        for m, scale in enumerate(scales):
            block = out[1 + 4 * m : 5 + 4 * m]
            columns.append(
                np.column_stack([(block[2 * j] - block[2 * j + 1]) / (2 * scale * h[j])
                                 for j in range(2)])
            )
        jacobian, error = columns[0], 0.0
        if richardson:
            jacobian = (4.0 * columns[0] - columns[1]) / 3.0
            error = float(np.max(np.abs(columns[0] - columns[1])) / 3.0
                          / max(np.max(np.abs(columns[0])), 1e-300))
        dv = self.parameter_step(value)
        derivatives = [
            (self.images(value + scale * dv, state)[0]
             - self.images(value - scale * dv, state)[0]) / (2.0 * scale * dv)
            for scale in scales
        ]
        derivative = derivatives[0]
        if richardson:
            derivative = (4.0 * derivatives[0] - derivatives[1]) / 3.0
        return Linearisation(image, jacobian, derivative, error)

    def _sensitivity_linearisation(self, value: float, state: np.ndarray) -> Linearisation:
        """The linearisation from one run of the forward sensitivities."""
        settings, dp, dt = self._direction(value)
        p = self.packed(value)
        duration = self.duration_s(value)
        run = simulate_sensitivities(p, float(state[0]), float(state[1]), np.array([duration]),
                                     settings=settings)
        if run.status != "ok":
            raise MapError(
                f"the integrator stopped ({run.status}) within {self.periods} period(s) from "
                f"(theta, theta') = ({state[0]:.6g}, {state[1]:.6g}) at {self.parameter} = "
                f"{value:.10g}"
            )
        image = np.array([run.theta[0], run.theta_dot[0]])
        jacobian = run.jacobian[0]
        derivative = jacobian[:, 2:] @ dp
        if dt != 0.0:  # the image is taken at T(value): the flow's rate times dT / dvalue
            rate = acceleration(duration, image[0], image[1], p)
            derivative = derivative + dt * np.array([image[1], rate])
        return Linearisation(image, jacobian[:, :2].copy(), derivative)

    def _packed_derivative(self, value: float) -> np.ndarray:
        """d p / d value of the packed vector: central differences of the packing (the
        one-sided three-point rule where a step leaves the physical range), exact to
        rounding where the packing is linear in the parameter, within about
        ``PACKING_RELATIVE_STEP`` squared of it elsewhere."""
        h = PACKING_RELATIVE_STEP * (abs(value) or self.parameter_scale)

        def pack(v: float) -> np.ndarray:
            return model_with(self.model, self.parameter, v).pack()

        try:
            return (pack(value + h) - pack(value - h)) / (2.0 * h)
        except ValueError:  # a value at the edge of its range (e.g. zeta = 0)
            pass
        for step in (h, -h):
            try:
                return (-3.0 * pack(value) + 4.0 * pack(value + step)
                        - pack(value + 2.0 * step)) / (2.0 * step)
            except ValueError:
                continue
        raise MapError(f"{self.parameter} = {value:.10g}: no packing on either side of it")

    def _moves_friction(self, value: float) -> bool:
        try:
            return bool(self._packed_derivative(value)[P.COULOMB_ACC] != 0.0)
        except MapError:
            return False

    def _direction(self, value: float) -> tuple[SensitivitySettings, np.ndarray, float]:
        """The sensitivity run's settings at ``value`` (the packed entries the parameter
        moves), their derivatives, and d T / d value (kept for the last value, and for
        every value when the packing is affine in the parameter, as it is for beta, A_m,
        f_drive_hz, theta_b_rad, zeta or mu0: the same derivatives at the first value and
        one a hundredth of the scale away)."""
        cache = self._direction_cache
        if cache is not None and (cache[0] == value or cache[0] is None):
            _, settings, dp, dt_per_duration = cache
            return settings, dp, dt_per_duration * self.duration_s(value)
        full = self._packed_derivative(value)
        affine = False
        if cache is None:
            with contextlib.suppress(MapError):  # no packing there: take it value by value
                affine = _same(full, self._packed_derivative(value + 1e-2 * self.parameter_scale))
        moved = [int(i) for i in np.flatnonzero(full) if int(i) not in _FOLLOWING]
        names = tuple(P(i).name for i in moved)
        settings = cache[1] if cache is not None else None
        if settings is None or settings.parameters != names:
            settings = SensitivitySettings(parameters=names, rtol=self.run_rtol,
                                           atol=self.run_atol)
        # T = 2 pi k / Omega: dT / dvalue = -T dOmega / Omega, kept per unit T
        dt_per_duration = -float(full[P.OMEGA_DRIVE]) / self.drive_rate(value)
        if affine and full[P.OMEGA_DRIVE] != 0.0:  # 1 / Omega is not affine: per value
            affine = False
        self._direction_cache = (None if affine else value, settings, full[moved],
                                 dt_per_duration)
        return settings, full[moved], dt_per_duration * self.duration_s(value)

    def orbit(self, value: float, state: np.ndarray,
              samples_per_period: int = ORBIT_SAMPLES_PER_PERIOD) -> OrbitSample:
        """The k periods after k periods from ``state``, sampled ``samples_per_period`` times
        per period, with their contacts and the largest angle and least barrier distance."""
        p = self.packed(value)
        duration = self.duration_s(value)
        fs = samples_per_period * self.periods / duration
        # the second pass is kept: a contact under way at drive phase 0 then counts once
        run = simulate_packed(
            p, float(state[0]), float(state[1]),
            settings=SimulationSettings(
                duration_s=duration, fs_hz=fs, skip_s=duration, poincare_phase=None,
                rtol=self.run_rtol, atol=self.run_atol,
            ),
        )
        if run.status != "ok":
            raise MapError(
                f"the integrator stopped ({run.status}) on the orbit from (theta, theta') = "
                f"({state[0]:.6g}, {state[1]:.6g}) at {self.parameter} = {value:.10g}"
            )
        theta_b = float(p[P.THETA_B])
        y, slope = run.theta, run.theta_dot
        # apexes: theta' goes from > 0 to <= 0 between samples (cyclically: the orbit closes)
        apexes = np.flatnonzero((slope > 0) & (np.roll(slope, -1) <= 0))
        heights = [_peak(run.t, y, slope, int(i)) for i in apexes] or [float(np.max(y))]
        top = max(heights)
        nearest = min(heights, key=lambda h: abs(theta_b - h))
        return OrbitSample(run.t, y, slope, run.contacts, top, theta_b - top, theta_b - nearest)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Two derivative vectors equal to rounding (relative 1e-9 of the larger entry)."""
    return bool(np.all(np.abs(a - b) <= 1e-9 * np.maximum(np.abs(a), np.abs(b))))


def _peak(t: np.ndarray, y: np.ndarray, slope: np.ndarray, i: int) -> float:
    """A local maximum of a sampled smooth curve next to sample i: the larger sample,
    refined on the cubic Hermite interpolant (values and slopes) on either side of it."""
    i = i if i + 1 >= y.size or y[i] >= y[i + 1] else i + 1
    best = float(y[i])
    for a in (i - 1, i):
        if a < 0 or a + 1 >= y.size:
            continue
        h = t[a + 1] - t[a]
        y0, y1, m0, m1 = y[a], y[a + 1], slope[a] * h, slope[a + 1] * h
        # derivative of the Hermite cubic in s on [0, 1]: c0 + c1 s + c2 s^2
        c0 = m0
        c1 = 2.0 * (-3.0 * y0 - 2.0 * m0 + 3.0 * y1 - m1)
        c2 = 3.0 * (2.0 * y0 + m0 - 2.0 * y1 + m1)
        for s in _real_roots(c2, c1, c0):
            if 0.0 < s < 1.0:
                value = (
                    (2 * s**3 - 3 * s**2 + 1) * y0 + (s**3 - 2 * s**2 + s) * m0
                    + (-2 * s**3 + 3 * s**2) * y1 + (s**3 - s**2) * m1
                )
                best = max(best, float(value))
    return best


def _real_roots(c2: float, c1: float, c0: float) -> list[float]:
    """The real roots of c2 s^2 + c1 s + c0 (a pair closer than 1e-12 to real counts as
    its real part), by the rounding-safe quadratic formula."""
    if c2 == 0.0:
        return [-c0 / c1] if c1 != 0.0 else []
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return [-c1 / (2.0 * c2)] if math.sqrt(-disc) < 2e-12 * abs(c2) else []
    q = -0.5 * (c1 + math.copysign(math.sqrt(disc), c1))
    return [q / c2, c0 / q] if q != 0.0 else [0.0]
