"""Families of periodic orbits through a model parameter: pseudo-arclength continuation of the
fixed points of the stroboscopic map, their Floquet multipliers, and the bifurcations on them.

Unknowns are u = (theta, theta' / Omega_0, value / scale) (Omega_0 the drive's angular
frequency at the start, scale the parameter range), so a step of 0.01 moves the orbit by
about 0.01 rad or the parameter by a hundredth of its range.  Each step predicts along the
tangent (the null vector of [P_x - I, P_value]) and corrects with Newton's method on
P^k(x) = x and the pseudo-arclength condition t . (u - u_predicted) = 0 (Keller).  The step
grows after easy corrections (<= 2 iterations) and halves after a failed one (no
convergence, the integrator stopped) or one that turns the tangent by more than
``MAX_TURN_RAD``.  Jacobians and the parameter derivative come from the period map: by
default from one run of the forward sensitivities per (state, value), the Floquet
multipliers the eigenvalues of that monodromy matrix.  With central differences (the
fallback with Coulomb friction, or ``jacobians="differences"``) tangents and multipliers
come from Richardson's Jacobians, and on a strongly unstable orbit (``|multiplier|`` in
the thousands, e.g. period 8 in the chaotic range) the bordered system is so
ill-conditioned that the plain differences' error stalls Newton's method: once a
correction shrinks the residual less than ``SLOW_CONVERGENCE``-fold,
the branch is corrected with Richardson's Jacobians, and the residual tolerance grows with
the largest multiplier (:func:`residual_tolerance`), as the map's rounding noise does.

Bifurcations are sign changes of test functions between neighbouring points, located by
the Illinois method on the arclength from the earlier point (every trial point corrected
onto the branch), until the arclength bracket is below ``LOCATE_TOLERANCE`` (about 1e-9 of
the parameter range):

* period-doubling: det(J + I) (a multiplier through -1);
* fold: the tangent's parameter component (the parameter turns back, a multiplier
  through +1); a multiplier through +1 without a turn, det(J - I) alone, is a branch point;
* grazing: the signed distance to the barrier of the swing's apex nearest it (a local
  maximum of theta; negative in contact) passes through zero: with the Hertzian or
  Kelvin-Voigt barrier this is where a contact begins.  Every apex counts, not only the
  largest angle: a second, low impact appearing on an orbit that already strikes is a
  grazing too.  When the apex nearest the barrier changes between two points, the change
  in the number of contacts is bisected instead.  With the stiff Hertzian contact the
  branch can turn within a few 1e-5 rad of a grazing, faster than the corrector follows
  (the map is C^1 there, its curvature huge): the branch then stops, saying so, with the
  grazing recorded at its last point, not located (bracket NaN).  Measured on one such
  branch with central differences: Newton's method at fixed parameter steps gets to
  within 1e-5 rad of the grazing, then finds no orbit (its residual stays at 6e-9): the
  branch turns there.  With the sensitivities the corrector follows the two branches
  where differences stopped so (the 10 Hz period-4 orbit of case (g)'s rig, its grazing
  located at beta = 0.106640866, and with a 0.02 rad gap, at 0.0269055) through the
  grazing, and on.

At a period-doubling of a period-k branch, the period-2k branch is followed from it: the
fixed point of P^2k next to the bifurcation, displaced along the eigenvector of the -1
multiplier (the 2k-map's pitchfork), is corrected and continued like the first branch.

Why not a library: pacopy (Euler-Newton, step control) asks for the residual, its
parameter derivative and a Jacobian solve as separate calls, so each would integrate the
map again, and it has no test functions or event location; pycont-lite is matrix-free
(Newton-Krylov) and detects folds, branch points and Hopf points of equilibria (stability
from eigenvalues' real parts), not multipliers through -1 of a map nor a non-smooth event
such as grazing.  With a 2 x 2 map whose Jacobian comes with every residual, the
predictor-corrector loop is a few dozen lines; the test functions and their location are
what matter, and those neither library provides.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from analysis.dynamics.period_map import (
    ORBIT_SAMPLES_PER_PERIOD,
    Linearisation,
    MapError,
    PeriodMap,
)
from analysis.dynamics.periodic_orbits import (
    NEWTON_TOLERANCE,
    ShootingError,
    find_periodic_orbit,
)
from analysis.progress import ProgressText

INITIAL_STEP = 0.01
MAX_STEP = 0.02
MIN_STEP = 1e-7
MAX_CORRECTOR_ITERATIONS = 7
MAP_ROUNDING_RAD = 1e-13  # the map's rounding noise at MAP_RTOL (measured, period_map)
NOISE_MARGIN = 100.0
SLOW_CONVERGENCE = 0.05  # a Newton step that shrinks the residual less: Richardson from then on
MAX_TURN_RAD = 0.1
MAX_POINTS = 4000
LOCATE_TOLERANCE = 1e-9
NEAR_GRAZING_RAD = 1e-4
SWITCH_STEP = 1e-3  # displacement along the -1 eigenvector to the period-2k branch
# when the arclength switch fails (a doubling beside a grazing: the map is nearly
# non-smooth there), the period-2k orbit is sought at fixed parameter offsets from the
# doubling (scaled units, either side), displaced by these fractions of SWITCH_STEP
SWITCH_OFFSETS = (1e-5, 1e-4, 1e-3)
SWITCH_FIXED_STEPS = (0.1, 1.0)

EVENT_KINDS = ("period_doubling", "fold", "branch_point", "grazing")  # grazing: contacts


class ContinuationError(RuntimeError):
    """The continuation could not start; the message says where and why."""


@dataclass(frozen=True)
class BranchPoint:
    """One periodic orbit on a branch: parameter value, state at drive phase 0, multipliers
    and the orbit's geometry (largest angle, least barrier distance, contacts, and its k
    angles at drive phase 0: where a bifurcation diagram's points lie)."""

    value: float
    state: np.ndarray
    multipliers: np.ndarray
    jacobian_error: float  # Richardson's estimate, relative
    tangent: np.ndarray  # unit tangent in scaled unknowns
    max_angle_rad: float
    barrier_distance_rad: float
    apex_distance_rad: float
    impact_speed_rad_s: float
    contacts: int  # per k periods
    section_theta: np.ndarray  # (k,) theta at drive phase 0: x, P(x), ..., P^(k-1)(x)
    iterations: int
    # the scaled system's Jacobian (2, 3) there: the corrector's first step from this point
    # (with the sensitivities; None with differences)
    system_jacobian: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def stable(self) -> bool:
        """All multipliers strictly inside the unit circle."""
        return bool(np.all(np.abs(self.multipliers) < 1.0))

    def test_function(self, kind: str) -> float:
        """The test function whose sign change marks an event of ``kind``."""
        trace = float(np.sum(self.multipliers).real)
        det = float(np.prod(self.multipliers).real)
        if kind == "period_doubling":
            return 1.0 + trace + det
        if kind == "fold":
            return float(self.tangent[2])
        if kind == "branch_point":
            return 1.0 - trace + det
        if kind == "grazing":
            return self.apex_distance_rad
        raise ValueError(f"unknown event kind {kind!r}; known: {EVENT_KINDS}")


@dataclass(frozen=True)
class BifurcationEvent:
    """A located bifurcation on branch ``branch``: its kind, parameter value (with the final
    bracket of the location; NaN when the branch stopped short of it), the orbit there and
    its multipliers."""

    kind: str
    branch: int
    periods: int
    value: float
    bracket: tuple[float, float]
    point: BranchPoint

    @property
    def label(self) -> str:
        """Short name for figures: PD, fold, BP, grazing."""
        return {"period_doubling": "PD", "fold": "fold", "branch_point": "BP",
                "grazing": "grazing"}[self.kind]


@dataclass
class Branch:
    """Consecutive periodic orbits of one period, in continuation order."""

    periods: int
    origin: str
    points: list[BranchPoint] = field(default_factory=list)
    events: list[BifurcationEvent] = field(default_factory=list)
    stop_reason: str = ""

    @property
    def values(self) -> np.ndarray:
        """Parameter value of each point."""
        return np.array([p.value for p in self.points])

    @property
    def states(self) -> np.ndarray:
        """(n, 2) states at drive phase 0."""
        return np.array([p.state for p in self.points]).reshape(-1, 2)

    @property
    def multipliers(self) -> np.ndarray:
        """(n, 2) complex multipliers, largest modulus first."""
        return np.array([p.multipliers for p in self.points]).reshape(-1, 2)

    @property
    def stable(self) -> np.ndarray:
        """Stability of each point."""
        return np.array([p.stable for p in self.points], dtype=bool)

    def column(self, name: str) -> np.ndarray:
        """One BranchPoint attribute of every point as an array."""
        return np.array([getattr(p, name) for p in self.points])


@dataclass
class ContinuationResult:
    """All branches followed from one start, and the time it took."""

    parameter: str
    bounds: tuple[float, float]
    branches: list[Branch]
    seconds: float
    map_rtol: float
    jacobians: str = "forward sensitivities"  # how the Jacobians were taken (PeriodMap's note)

    @property
    def events(self) -> list[BifurcationEvent]:
        """Every located bifurcation, branch by branch in continuation order."""
        return [event for branch in self.branches for event in branch.events]

    @property
    def points(self) -> int:
        """Orbits computed on all branches."""
        return sum(len(b.points) for b in self.branches)

    @property
    def seconds_per_point(self) -> float:
        """Wall time per branch point (event location included)."""
        return self.seconds / max(self.points, 1)


def residual_tolerance(multipliers: np.ndarray) -> float:
    """The corrector's residual tolerance: NEWTON_TOLERANCE, or ``NOISE_MARGIN`` times the
    map's rounding noise magnified by the largest multiplier when that is larger (a
    strongly unstable orbit's residual cannot fall below the magnified noise)."""
    largest = float(np.max(np.abs(multipliers)))
    return max(NEWTON_TOLERANCE, NOISE_MARGIN * MAP_ROUNDING_RAD * largest)


class _Branching:
    """The scaled problem of one period map: residual, Jacobian, corrector, points."""

    def __init__(self, period_map: PeriodMap, drive_rate: float) -> None:
        self.map = period_map
        self.scale = np.array([1.0, drive_rate])
        self.value_scale = period_map.parameter_scale
        self.precise = False  # Richardson Jacobians in the corrector, once plain ones fell short

    def unknowns(self, state: np.ndarray, value: float) -> np.ndarray:
        return np.array([state[0], state[1] / self.scale[1], value / self.value_scale])

    def split(self, u: np.ndarray) -> tuple[np.ndarray, float]:
        return u[:2] * self.scale, float(u[2] * self.value_scale)

    def system(self, u: np.ndarray, richardson: bool = False):
        """Scaled residual (2,), its Jacobian (2, 3) and the map's linearisation at u."""
        x, value = self.split(u)
        lin = self.map.linearise(value, x, richardson=richardson)
        residual = (lin.image - x) / self.scale
        jac = np.empty((2, 3))
        jac[:, :2] = (lin.jacobian - np.eye(2)) * self.scale[None, :] / self.scale[:, None]
        jac[:, 2] = lin.parameter_derivative * self.value_scale / self.scale
        return residual, jac, lin

    @staticmethod
    def tangent(jac: np.ndarray, previous: np.ndarray) -> np.ndarray:
        t = np.cross(jac[0], jac[1])
        t /= np.linalg.norm(t)
        return t if t @ previous >= 0 else -t

    def correct(self, predicted: np.ndarray, normal: np.ndarray, previous_tangent: np.ndarray,
                near: BranchPoint | None = None):
        """Newton on P^k(x) = x with normal . (u - predicted) = 0; the BranchPoint, or None.

        With exact Jacobians (the sensitivities) and ``near``, a converged point near the
        prediction, the first step takes ``near``'s Jacobian and only the map's image at
        the prediction (a chord step: the Jacobian moves by O(step), the step it corrects
        is O(step^2))."""
        u = predicted.copy()
        previous = math.inf
        exact = self.map.jacobian_method == "sensitivities"
        chord = exact and near is not None and near.system_jacobian is not None
        for iteration in range(1, MAX_CORRECTOR_ITERATIONS + 1):
            try:
                if chord:
                    x, value = self.split(u)
                    residual = (self.map.images(value, x)[0] - x) / self.scale
                    jac = near.system_jacobian
                    chord = float(np.linalg.norm(residual)) >= residual_tolerance(
                        near.multipliers)
                if not chord:  # (a prediction already on the branch: the point's own)
                    residual, jac, lin = self.system(u, richardson=self.precise)
            except MapError:
                return None
            if not np.all(np.isfinite(jac)) or not np.all(np.isfinite(residual)):
                return None
            size = float(np.linalg.norm(residual))
            if not chord and size < residual_tolerance(lin.multipliers):
                # exact derivatives need no second, Richardson, linearisation at the point
                return self.point(u, previous_tangent, iteration,
                                  (jac, lin) if exact else None)
            chord = False
            # Newton's method slowed to linear convergence: the plain differences' error,
            # magnified by an ill-conditioned system (|multiplier| >> 1), is the cause; the
            # rest of the branch is corrected with Richardson's Jacobians
            self.precise = self.precise or size > SLOW_CONVERGENCE * previous
            previous = size
            matrix = np.vstack([jac, normal])
            rhs = -np.concatenate([residual, [normal @ (u - predicted)]])
            try:
                u = u + np.linalg.solve(matrix, rhs)
            except np.linalg.LinAlgError:
                return None
        return None

    def point(self, u: np.ndarray, previous_tangent: np.ndarray, iterations: int,
              linearised: tuple[np.ndarray, Linearisation] | None = None) -> BranchPoint | None:
        """The BranchPoint at a converged u: multipliers and tangent (from ``linearised``,
        the system's Jacobian and the map's linearisation at u, or Richardson's), orbit
        geometry."""
        x, value = self.split(u)
        try:
            if linearised is None:
                _, jac, lin = self.system(u, richardson=True)
            else:
                jac, lin = linearised
            orbit = self.map.orbit(value, x)
        except MapError:
            return None
        return BranchPoint(
            value=value, state=x, multipliers=lin.multipliers,
            jacobian_error=lin.jacobian_error, tangent=self.tangent(jac, previous_tangent),
            max_angle_rad=orbit.max_angle_rad, barrier_distance_rad=orbit.barrier_distance_rad,
            apex_distance_rad=orbit.apex_distance_rad,
            impact_speed_rad_s=orbit.impact_speed_rad_s, contacts=orbit.contacts.count,
            section_theta=orbit.theta[::ORBIT_SAMPLES_PER_PERIOD][: self.map.periods].copy(),
            iterations=iterations,
            system_jacobian=jac if linearised is not None else None,
        )


def continue_orbits(
    period_map: PeriodMap,
    start: float,
    stop: float,
    guess: np.ndarray,
    *,
    max_periods: int | None = None,
    max_points: int = MAX_POINTS,
    max_step: float = MAX_STEP,
    progress: ProgressText | None = None,
) -> ContinuationResult:
    """Follow the period-k orbit through ``guess`` at ``start`` towards ``stop`` (k =
    ``period_map.periods``), and the period-2k, 4k ... branches born at its
    period-doublings up to ``max_periods`` (default 4 k; k itself: no switching).

    Every branch ends where it leaves [min(start, stop), max(start, stop)], after
    ``max_points`` points, or where the step falls below ``MIN_STEP`` (its
    ``stop_reason`` says which).  ContinuationError when Newton's method finds no orbit
    at the start.
    """
    started = time.perf_counter()
    if start == stop:
        raise ValueError(f"start = stop = {start}: nothing to continue over")
    max_periods = 4 * period_map.periods if max_periods is None else max_periods
    bounds = (min(start, stop), max(start, stop))
    scale = abs(stop - start)
    period_map = PeriodMap(period_map.model, period_map.parameter, period_map.periods,
                           parameter_scale=scale, rtol=period_map.rtol, atol=period_map.atol,
                           jacobians=period_map.jacobians)
    try:
        orbit = find_periodic_orbit(period_map, start, guess)
    except ShootingError as error:
        raise ContinuationError(str(error)) from None
    drive_rate = period_map.drive_rate(start)
    problem = _Branching(period_map, drive_rate)
    direction = math.copysign(1.0, stop - start)
    u0 = problem.unknowns(orbit.state, start)
    first = problem.point(u0, np.array([0.0, 0.0, direction]), orbit.iterations)
    if first is None:
        raise ContinuationError(f"the orbit found at {period_map.parameter} = {start} cannot "
                                "be sampled (the integrator stopped)")
    origin = f"period-{period_map.periods} orbit at {period_map.parameter} = {start:g}"
    branches = [Branch(period_map.periods, origin, [first])]
    queue = [(0, problem)]
    while queue:
        index, branch_problem = queue.pop(0)
        branch = branches[index]
        _follow(branch_problem, branch, index, bounds, max_points, max_step, progress)
        for event in list(branch.events):
            if event.kind != "period_doubling" or 2 * branch.periods > max_periods:
                continue
            switched = _switch_at_period_doubling(branch_problem, event, drive_rate)
            if switched is None:
                branch.stop_reason += (f"; no period-{2 * branch.periods} branch found at "
                                       f"the period-doubling at {event.value:.8g}")
                continue
            new_problem, point = switched
            origin = (f"period-doubling of branch {index} (period {branch.periods}) at "
                      f"{period_map.parameter} = {event.value:.8g}")
            branches.append(Branch(2 * branch.periods, origin, [point]))
            queue.append((len(branches) - 1, new_problem))
    return ContinuationResult(period_map.parameter, bounds, branches,
                              time.perf_counter() - started, period_map.run_rtol,
                              period_map.jacobian_note)


def _follow(problem: _Branching, branch: Branch, index: int, bounds: tuple[float, float],
            max_points: int, max_step: float, progress: ProgressText | None) -> None:
    """Extend ``branch`` from its last point until it leaves ``bounds`` or the step fails."""
    h = min(INITIAL_STEP, max_step)
    name = problem.map.parameter
    while len(branch.points) < max_points:
        last = branch.points[-1]
        u_last = problem.unknowns(last.state, last.value)
        predicted = u_last + h * last.tangent
        point = problem.correct(predicted, last.tangent, last.tangent, last)
        turned = point is not None and point.tangent @ last.tangent < math.cos(MAX_TURN_RAD)
        if point is None or turned:
            h *= 0.5
            if h < MIN_STEP:
                _stop_stalled(branch, index, last, name,
                              "the tangent turns too fast" if turned else
                              "Newton's method does not converge there (or the integrator stops)")
                return
            continue
        outside = not bounds[0] <= point.value <= bounds[1]
        if outside:
            edge = bounds[1] if point.value > bounds[1] else bounds[0]
            point = _point_at_value(problem, last, edge) or point
        _detect(problem, branch, index, last, point)
        branch.points.append(point)
        if progress is not None:
            progress(f"branch {index} (period {branch.periods}): {len(branch.points)} points, "
                     f"{name} = {point.value:.6g}, {'stable' if point.stable else 'unstable'}")
        if outside:
            branch.stop_reason = f"left the range at {name} = {point.value:.8g}"
            return
        if point.iterations <= 3:  # two Newton steps or fewer
            h = min(1.5 * h, max_step)
        elif point.iterations >= 6:
            h *= 0.7
            if h < MIN_STEP:
                _stop_stalled(branch, index, point, name, "Newton's method converges too slowly")
                return
    branch.stop_reason = f"{max_points} points reached"


def _stop_stalled(branch: Branch, index: int, last: BranchPoint, name: str, why: str) -> None:
    """End a branch whose step fell below MIN_STEP; a grazing within NEAR_GRAZING_RAD of the
    last point is recorded there (the corrector cannot cross it)."""
    branch.stop_reason = f"step below {MIN_STEP:g} at {name} = {last.value:.8g}: {why}"
    if abs(last.apex_distance_rad) < NEAR_GRAZING_RAD:
        branch.stop_reason += (f" (an apex {last.apex_distance_rad:.2g} rad from the barrier: "
                               "a grazing the branch cannot cross)")
        branch.events.append(BifurcationEvent("grazing", index, branch.periods, last.value,
                                              (math.nan, math.nan), last))


def _point_at_value(problem: _Branching, last: BranchPoint, value: float) -> BranchPoint | None:
    """The orbit on the branch at exactly ``value`` (the range's end), corrected from ``last``."""
    u_last = problem.unknowns(last.state, last.value)
    target = value / problem.value_scale
    if abs(last.tangent[2]) < 1e-12:
        return None
    predicted = u_last + (target - u_last[2]) / last.tangent[2] * last.tangent
    return problem.correct(predicted, np.array([0.0, 0.0, 1.0]), last.tangent, last)


def _detect(problem: _Branching, branch: Branch, index: int, before: BranchPoint,
            after: BranchPoint) -> None:
    """Locate every test function's sign change, and every change in the number of
    contacts (grazing), between two neighbouring points."""
    folded = np.sign(before.test_function("fold")) != np.sign(after.test_function("fold"))
    for kind in EVENT_KINDS:
        if kind == "grazing" and before.contacts != after.contacts and np.sign(
            before.apex_distance_rad
        ) == np.sign(after.apex_distance_rad):  # the apex nearest the barrier changed
            middle = 0.5 * (before.contacts + after.contacts)
            located = _locate(problem, before, after, lambda p, m=middle: p.contacts - m,
                              bisect=True)
        else:
            a, b = before.test_function(kind), after.test_function(kind)
            if a == 0.0 or np.sign(a) == np.sign(b):
                continue
            if kind == "branch_point" and folded:
                continue  # the fold's own multiplier +1
            located = _locate(problem, before, after,
                              lambda p, k=kind: p.test_function(k), bisect=False)
        if located is not None:
            point, bracket = located
            branch.events.append(
                BifurcationEvent(kind, index, branch.periods, 0.5 * sum(bracket), bracket, point)
            )


def _locate(problem: _Branching, before: BranchPoint, after: BranchPoint,
            function: Callable[[BranchPoint], float], *, bisect: bool):
    """The corrected point, on the arclength s from ``before``, where ``function`` changes
    sign (Illinois, or bisection for a step function), and the parameter bracket of the
    final arclength bracket."""
    u0 = problem.unknowns(before.state, before.value)
    u1 = problem.unknowns(after.state, after.value)
    tangent = before.tangent
    lo, hi = 0.0, float(tangent @ (u1 - u0))
    f_lo, f_hi = function(before), function(after)
    p_lo, p_hi = before, after
    side = 0
    for _ in range(80):
        if abs(hi - lo) < LOCATE_TOLERANCE:
            break
        s = 0.5 * (lo + hi) if bisect else (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not min(lo, hi) < s < max(lo, hi):
            s = 0.5 * (lo + hi)
        point = problem.correct(u0 + s * tangent, tangent, tangent, before)
        if point is None:
            return None
        f = function(point)
        if f == 0.0:
            p_lo = p_hi = point
            break
        if np.sign(f) == np.sign(f_lo):
            lo, f_lo, p_lo = s, f, point
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi, p_hi = s, f, point
            if side == 1:
                f_lo *= 0.5
            side = 1
    best = p_lo if abs(function(p_lo)) <= abs(function(p_hi)) else p_hi
    return best, (min(p_lo.value, p_hi.value), max(p_lo.value, p_hi.value))


def _switch_at_period_doubling(problem: _Branching, event: BifurcationEvent, drive_rate: float):
    """The first point of the period-2k branch born at ``event``, or None.

    First the pseudo-arclength switch: displaced along the multiplier -1's eigenvector,
    the parameter free.  Where that finds nothing (a doubling a hair past a grazing, where
    the map is nearly non-smooth and the free parameter sends Newton across the barrier),
    the period-2k orbit is sought at fixed parameter values on either side of the doubling
    (``SWITCH_OFFSETS``): a flip is super- or subcritical, and the branch lies on one side."""
    point = event.point
    doubled = _Branching(problem.map.with_periods(2 * problem.map.periods), drive_rate)
    try:
        lin = problem.map.linearise(point.value, point.state)
    except MapError:
        return None
    values, vectors = np.linalg.eig(lin.jacobian)
    j = int(np.argmin(np.abs(values + 1.0)))
    v = np.real(vectors[:, j]) / doubled.scale
    v /= np.linalg.norm(v)
    u_pd = doubled.unknowns(point.state, point.value)
    direction = np.array([v[0], v[1], 0.0])
    fixed = np.array([0.0, 0.0, 1.0])
    attempts = [(u_pd + step * direction, direction, step)
                for step in (SWITCH_STEP, 3 * SWITCH_STEP, 10 * SWITCH_STEP)]
    attempts += [(u_pd + fraction * SWITCH_STEP * direction + side * offset * fixed, fixed,
                  fraction * SWITCH_STEP)
                 for offset in SWITCH_OFFSETS for side in (-1.0, 1.0)
                 for fraction in SWITCH_FIXED_STEPS]
    for predicted, normal, step in attempts:
        candidate = doubled.correct(predicted, normal, direction)
        if candidate is None:
            continue
        x = candidate.state
        try:
            once = problem.map.images(candidate.value, x)[0]
        except MapError:
            continue
        if np.linalg.norm((once - x) / doubled.scale) < 0.5 * step:
            continue  # fell back onto the period-k orbit
        away = doubled.unknowns(x, candidate.value) - u_pd
        if candidate.tangent @ away < 0:
            candidate = replace(candidate, tangent=-candidate.tangent)
        return doubled, candidate
    return None
