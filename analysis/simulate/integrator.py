"""Compiled Dormand-Prince 8(5,3) integrator of the impact pendulum with exact event location.

The whole integration loop is one numba function (``integrate``) working on plain
arrays, so a call costs no Python per step.  The non-smooth parts of the model are
handled by splitting the motion into regions, each integrated with a smooth
right-hand side, and by landing exactly on the surfaces between them:

* free flight / contact: the contact surface theta = theta_b.  A step that crosses
  it (sign change of theta - theta_b at its end) or grazes it (an extremum of the
  step's dense-output polynomial beyond the surface, the case a sign test misses)
  is cut at the first crossing found on the dense output; the state there (from a
  step of that length at an entry, from the dense output at an exit) is put exactly
  on the surface by one Henon step (theta as the independent variable).
* Coulomb friction: sliding in a fixed direction until theta' = 0 (located the same
  way, landed with theta' as the independent variable), then stuck while the other
  torques stay within the friction torque; the release time is located on the
  (time-only) acceleration function.

The integrator keeps its state in a small float vector (layout ``S_*``) so that a
streaming caller can continue a run across calls; the last step's dense-output
polynomial stays valid, so outputs at any time inside it cost a few flops.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop853

from analysis.model import (
    K_GAIN,
    K_SHAFT,
    K_STIFFNESS,
    P,
    coefficients,
    region_acceleration,
    sliding_acceleration,
    sliding_direction,
)

# Every kernel below may fuse a*b + c into one rounded fma (LLVM's "contract" only: no
# reordering, no NaN or infinity shortcuts).  The Runge-Kutta stage sums are chains of
# products: measured, the impact decay runs 10 % and case h 4 % faster.
kernel = functools.partial(numba.njit, cache=True, fastmath={"contract"})

# ----------------------------------------------------------------------------- status codes

STATUS_OK = 0
STATUS_OVER_THE_TOP = 1
STATUS_MAX_STEPS = 2
STATUS_STEP_UNDERFLOW = 3
STATUS_NAMES = {
    STATUS_OK: "ok",
    STATUS_OVER_THE_TOP: "over_the_top",
    STATUS_MAX_STEPS: "max_steps",
    STATUS_STEP_UNDERFLOW: "step_size_underflow",
}

# ----------------------------------------------------------------------------- state layout

S_TA = 0  # start time of the current segment (step, step cut at an event, or stuck interval)
S_TB = 1  # its end time: the integrator's own "now"
S_THA = 2  # theta at TA
S_OMA = 3  # theta' at TA
S_THB = 4  # theta at TB
S_OMB = 5  # theta' at TB
DEGREE = 7  # of the dense-output polynomials
S_POLY = 6  # 2 x 7 dense-output coefficients: theta(s) = THA + c0 s + .. + c6 s^7, then theta'
S_H = S_POLY + 2 * DEGREE  # next step size proposal (<= 0: choose one)
S_CONTACT = S_H + 1  # 1.0 while theta > theta_b (in contact), else 0.0
S_SLIDE = S_H + 2  # Coulomb sliding direction +1 / -1, 0 stuck (always +1 without friction)
S_STATUS = S_H + 3
S_ENTRY_T = S_H + 4  # current contact: entry time, theta, theta', grazing flag, max theta so far
S_ENTRY_TH = S_H + 5
S_ENTRY_OM = S_H + 6
S_ENTRY_GRAZE = S_H + 7
S_THMAX = S_H + 8
S_STEPS = S_H + 9  # accepted steps
S_REJECTS = S_H + 10
S_STICK_T = S_H + 11  # start of the current stuck interval
S_ACC_B = S_H + 12  # theta'' at TB (last stage of the step), valid when S_ACC_OK = 1
S_ACC_OK = S_H + 13
S_FREE_H = S_H + 14  # step size free flight proposed when the current contact began
S_EXIT_H = S_H + 15  # current contact: shortest step of the approach to its exit (0: unknown)
S_SIZE = S_H + 16

# rows of the event buffer
EV_KIND = 0  # 0 contact, 1 stuck interval
EV_T_IN = 1
EV_TH_IN = 2
EV_OM_IN = 3
EV_T_OUT = 4
EV_TH_OUT = 5
EV_OM_OUT = 6
EV_DELTA_MAX = 7
EV_GRAZING = 8
EV_SIZE = 9
KIND_CONTACT = 0.0
KIND_STICK = 1.0

# ------------------------------------------------------------------------- Dormand-Prince 8(5,3)
# The published DOP853 tableau (Hairer, Norsett & Wanner, Solving ODEs I, section II.10) with
# its 7th-order dense output, taken from scipy's copy of it; numba freezes the arrays into
# the compiled kernel as constants.
N_STAGES = _dop853.N_STAGES  # 12 stages per step; stage 13 is f at the step's end
A853 = np.ascontiguousarray(_dop853.A, dtype=np.float64)
B853 = np.ascontiguousarray(_dop853.B, dtype=np.float64)
C853 = np.ascontiguousarray(_dop853.C, dtype=np.float64)
E3 = np.ascontiguousarray(_dop853.E3, dtype=np.float64)
E5 = np.ascontiguousarray(_dop853.E5, dtype=np.float64)
D853 = np.ascontiguousarray(_dop853.D, dtype=np.float64)
N_EXTENDED = _dop853.N_STAGES_EXTENDED  # 16 with the three extra dense-output stages
# the step and its dense output skip the stages 1-4 where the later rows are zero
assert not D853[:, 1:5].any() and not A853[N_STAGES:, 1:5].any()


def _power_basis() -> np.ndarray:
    """M with y(s) - y0 = sum_j (M F)_j s^(j+1) for the interpolant's nested form
    y0 + s (F0 + (1-s) (F1 + s (F2 + (1-s) (F3 + ...)))), so polynomials are plain."""
    basis = np.zeros((DEGREE, DEGREE))
    s = np.polynomial.Polynomial([0.0, 1.0])
    for i in range(DEGREE):
        poly = np.polynomial.Polynomial([0.0])
        for j in range(DEGREE - 1, -1, -1):
            poly = poly + (1.0 if j == i else 0.0)
            poly = poly * (s if j % 2 == 0 else 1.0 - s)
        padded = np.zeros(DEGREE + 1)
        padded[: poly.coef.size] = poly.coef
        basis[:, i] = padded[1:]
    return basis


M_POWER = np.ascontiguousarray(_power_basis())

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ENTRY_STEP_FRACTION = 0.005
# Leaving contact, a step is kept to this fraction of the estimated time to the surface: the
# force's delta^1.5 end makes longer trial steps fail, several times per contact, as the
# controller shrinks them only by err^(-1/8).  Once that fraction is below the entry step,
# the step is sized to cross just beyond the estimated exit instead.
EXIT_STEP_FRACTION = 0.7
EXIT_CROSSING_FACTOR = 1.05
SLOW_ENTRY = 0.1  # entry speed below this fraction of the step's: land with a step of its own
H_MIN_RELATIVE = 1e-14  # smallest step, relative to max(1 s, |t|): below it t + h == t nearly
STUCK_SCAN_PER_PERIOD = 128  # release search resolution while stuck under forcing


# ----------------------------------------------------------------------------- right-hand side
# The right-hand side is analysis.model's definition of the equations, not a copy: its
# functions are inlined into these kernels (and compiled with their flags).  numba's cache
# tracks only a kernel's own file, so after editing the equations in analysis/model.py
# delete this folder's __pycache__ (tests/simulate/test_rhs.py finds a stale cache: the
# kernels' right-hand side then differs from the model's).


@kernel
def rhs(t, th, om, pr, slide, tc):
    """The right-hand side theta'' every step integrates: the model's equation for the
    region's coefficients ``pr`` (contact term or not), sliding in direction ``slide``
    against the friction acceleration ``tc``."""
    return sliding_acceleration(t, th, om, pr, slide, tc)


@kernel(inline="always")  # one call site; a call would pass ~40 arguments
def _rk_step(t, th, om, a0, h, pr, slide, tc, kth, kom, rtol, atol, om_floor):
    """One DOP853 step: fills the stage slopes; returns theta, theta', theta'' at the end and
    the scaled error norm (Hairer's blend of the 5th- and 3rd-order estimates), with theta'
    measured relative to max(|theta'|, om_floor).

    The stages are written out term by term, zeros of the tableau left out (as in Hairer's
    own code): a loop over the tableau costs ~10 % more per step.  Stage s is at
    (t + c_s h, theta + h sum_j a_sj v_j, v_s = theta' + h sum_j a_sj theta''_j).
    """
    A = A853
    v0 = om
    v1 = om + h * (A[1, 0] * a0)
    a1 = rhs(t + C853[1] * h, th + h * (A[1, 0] * v0), v1, pr, slide, tc)
    v2 = om + h * (A[2, 0] * a0 + A[2, 1] * a1)
    a2 = rhs(t + C853[2] * h, th + h * (A[2, 0] * v0 + A[2, 1] * v1), v2, pr, slide, tc)
    v3 = om + h * (A[3, 0] * a0 + A[3, 2] * a2)
    a3 = rhs(t + C853[3] * h, th + h * (A[3, 0] * v0 + A[3, 2] * v2), v3, pr, slide, tc)
    v4 = om + h * (A[4, 0] * a0 + A[4, 2] * a2 + A[4, 3] * a3)
    a4 = rhs(
        t + C853[4] * h, th + h * (A[4, 0] * v0 + A[4, 2] * v2 + A[4, 3] * v3), v4, pr, slide, tc
    )
    v5 = om + h * (A[5, 0] * a0 + A[5, 3] * a3 + A[5, 4] * a4)
    a5 = rhs(
        t + C853[5] * h, th + h * (A[5, 0] * v0 + A[5, 3] * v3 + A[5, 4] * v4), v5, pr, slide, tc
    )
    v6 = om + h * (A[6, 0] * a0 + A[6, 3] * a3 + A[6, 4] * a4 + A[6, 5] * a5)
    d6 = A[6, 0] * v0 + A[6, 3] * v3 + A[6, 4] * v4 + A[6, 5] * v5
    a6 = rhs(t + C853[6] * h, th + h * d6, v6, pr, slide, tc)
    v7 = om + h * (A[7, 0] * a0 + A[7, 3] * a3 + A[7, 4] * a4 + A[7, 5] * a5 + A[7, 6] * a6)
    d7 = A[7, 0] * v0 + A[7, 3] * v3 + A[7, 4] * v4 + A[7, 5] * v5 + A[7, 6] * v6
    a7 = rhs(t + C853[7] * h, th + h * d7, v7, pr, slide, tc)
    v8 = om + h * (
        A[8, 0] * a0 + A[8, 3] * a3 + A[8, 4] * a4 + A[8, 5] * a5 + A[8, 6] * a6 + A[8, 7] * a7
    )
    d8 = A[8, 0] * v0 + A[8, 3] * v3 + A[8, 4] * v4 + A[8, 5] * v5 + A[8, 6] * v6 + A[8, 7] * v7
    a8 = rhs(t + C853[8] * h, th + h * d8, v8, pr, slide, tc)
    v9 = om + h * (
        A[9, 0] * a0
        + A[9, 3] * a3
        + A[9, 4] * a4
        + A[9, 5] * a5
        + A[9, 6] * a6
        + A[9, 7] * a7
        + A[9, 8] * a8
    )
    d9 = (
        A[9, 0] * v0
        + A[9, 3] * v3
        + A[9, 4] * v4
        + A[9, 5] * v5
        + A[9, 6] * v6
        + A[9, 7] * v7
        + A[9, 8] * v8
    )
    a9 = rhs(t + C853[9] * h, th + h * d9, v9, pr, slide, tc)
    v10 = om + h * (
        A[10, 0] * a0
        + A[10, 3] * a3
        + A[10, 4] * a4
        + A[10, 5] * a5
        + A[10, 6] * a6
        + A[10, 7] * a7
        + A[10, 8] * a8
        + A[10, 9] * a9
    )
    d10 = (
        A[10, 0] * v0
        + A[10, 3] * v3
        + A[10, 4] * v4
        + A[10, 5] * v5
        + A[10, 6] * v6
        + A[10, 7] * v7
        + A[10, 8] * v8
        + A[10, 9] * v9
    )
    a10 = rhs(t + C853[10] * h, th + h * d10, v10, pr, slide, tc)
    v11 = om + h * (
        A[11, 0] * a0
        + A[11, 3] * a3
        + A[11, 4] * a4
        + A[11, 5] * a5
        + A[11, 6] * a6
        + A[11, 7] * a7
        + A[11, 8] * a8
        + A[11, 9] * a9
        + A[11, 10] * a10
    )
    d11 = (
        A[11, 0] * v0
        + A[11, 3] * v3
        + A[11, 4] * v4
        + A[11, 5] * v5
        + A[11, 6] * v6
        + A[11, 7] * v7
        + A[11, 8] * v8
        + A[11, 9] * v9
        + A[11, 10] * v10
    )
    a11 = rhs(t + C853[11] * h, th + h * d11, v11, pr, slide, tc)
    # the 8th-order solution and the two error estimates share stages 0 and 5-11
    B = B853
    th1 = th + h * (
        B[0] * v0
        + B[5] * v5
        + B[6] * v6
        + B[7] * v7
        + B[8] * v8
        + B[9] * v9
        + B[10] * v10
        + B[11] * v11
    )
    om1 = om + h * (
        B[0] * a0
        + B[5] * a5
        + B[6] * a6
        + B[7] * a7
        + B[8] * a8
        + B[9] * a9
        + B[10] * a10
        + B[11] * a11
    )
    a12 = rhs(t + h, th1, om1, pr, slide, tc)
    e5th = (
        E5[0] * v0
        + E5[5] * v5
        + E5[6] * v6
        + E5[7] * v7
        + E5[8] * v8
        + E5[9] * v9
        + E5[10] * v10
        + E5[11] * v11
    )
    e5om = (
        E5[0] * a0
        + E5[5] * a5
        + E5[6] * a6
        + E5[7] * a7
        + E5[8] * a8
        + E5[9] * a9
        + E5[10] * a10
        + E5[11] * a11
    )
    e3th = (
        E3[0] * v0
        + E3[5] * v5
        + E3[6] * v6
        + E3[7] * v7
        + E3[8] * v8
        + E3[9] * v9
        + E3[10] * v10
        + E3[11] * v11
    )
    e3om = (
        E3[0] * a0
        + E3[5] * a5
        + E3[6] * a6
        + E3[7] * a7
        + E3[8] * a8
        + E3[9] * a9
        + E3[10] * a10
        + E3[11] * a11
    )
    # the stages the dense output needs
    kth[0], kom[0] = v0, a0
    kth[5], kom[5] = v5, a5
    kth[6], kom[6] = v6, a6
    kth[7], kom[7] = v7, a7
    kth[8], kom[8] = v8, a8
    kth[9], kom[9] = v9, a9
    kth[10], kom[10] = v10, a10
    kth[11], kom[11] = v11, a11
    kth[12], kom[12] = om1, a12
    sth = atol + rtol * max(abs(th), abs(th1))
    som = atol + rtol * max(abs(om), abs(om1), om_floor)
    e5 = (e5th / sth) ** 2 + (e5om / som) ** 2
    e3 = (e3th / sth) ** 2 + (e3om / som) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return th1, om1, a12, 0.0
    return th1, om1, a12, abs(h) * e5 / math.sqrt(2.0 * (e5 + 0.01 * e3))


@kernel
def _step_factor(err):
    """The controller's step ratio SAFETY err^(-1/8) for an 8th-order local error (three
    square roots: a pow costs about twice as much, once per step)."""
    return SAFETY / math.sqrt(math.sqrt(math.sqrt(err)))


@kernel
def _dense_coefficients(t, th, om, th1, om1, h, pr, slide, tc, kth, kom, S):
    """Coefficients of the 7th-order dense-output polynomials of a step, into S.

    Needs the step's stages in kth/kom; evaluates the three extra stages of the
    interpolant (only for steps that are sampled or searched for events).
    """
    for s in range(N_STAGES + 1, N_EXTENDED):
        dth = A853[s, 0] * kth[0]
        dom = A853[s, 0] * kom[0]
        for j in range(5, s):  # _rk_step keeps stages 0 and 5-12 only
            a = A853[s, j]
            dth += a * kth[j]
            dom += a * kom[j]
        v = om + h * dom
        kth[s] = v
        kom[s] = rhs(t + C853[s] * h, th + h * dth, v, pr, slide, tc)
    for comp in range(2):
        k = kth if comp == 0 else kom
        delta = (th1 - th) if comp == 0 else (om1 - om)
        # the interpolant's terms as scalars (no scratch array: this runs for nearly every
        # step); stages 1-4 have zero weight in D853 and are skipped
        f0 = delta
        f1 = h * k[0] - delta
        f2 = 2.0 * delta - h * (k[N_STAGES] + k[0])
        d0 = D853[0, 0] * k[0]
        d1 = D853[1, 0] * k[0]
        d2 = D853[2, 0] * k[0]
        d3 = D853[3, 0] * k[0]
        for j in range(5, N_EXTENDED):
            kj = k[j]
            d0 += D853[0, j] * kj
            d1 += D853[1, j] * kj
            d2 += D853[2, j] * kj
            d3 += D853[3, j] * kj
        f3 = h * d0
        f4 = h * d1
        f5 = h * d2
        f6 = h * d3
        base = S_POLY + DEGREE * comp
        for j in range(DEGREE):
            S[base + j] = (
                M_POWER[j, 0] * f0
                + M_POWER[j, 1] * f1
                + M_POWER[j, 2] * f2
                + M_POWER[j, 3] * f3
                + M_POWER[j, 4] * f4
                + M_POWER[j, 5] * f5
                + M_POWER[j, 6] * f6
            )


@kernel
def _poly(y0, S, base, s):
    acc = S[base + DEGREE - 1]
    for j in range(DEGREE - 2, -1, -1):
        acc = S[base + j] + s * acc
    return y0 + s * acc


@kernel
def _rescale_poly(S, r):
    """Both polynomials of S re-expressed on the first fraction ``r`` of their interval."""
    scale = 1.0
    for j in range(DEGREE):
        scale *= r
        S[S_POLY + j] *= scale
        S[S_POLY + DEGREE + j] *= scale


@kernel
def _poly_slope(S, base, s):
    acc = DEGREE * S[base + DEGREE - 1]
    for j in range(DEGREE - 2, -1, -1):
        acc = (j + 1) * S[base + j] + s * acc
    return acc


@kernel
def _first_exit(y0, S, base, level, sign):
    """First s in [0, 1] where d(s) = sign (poly(s) - level) goes from >= 0 to < 0, else -1.

    The interval is cut at the polynomial's critical points (roots of its cubic
    derivative, bracketed on a fine grid), so d is monotone on each piece and an
    excursion that starts and ends inside the step (grazing) is found as well.
    """
    nodes = np.empty(DEGREE + 2)
    nodes[0] = 0.0
    count = 1
    samples = 24
    prev = sign * _poly_slope(S, base, 0.0)
    for j in range(1, samples + 1):
        s = j / samples
        cur = sign * _poly_slope(S, base, s)
        if (prev < 0.0 <= cur) or (prev > 0.0 >= cur):
            lo = (j - 1) / samples
            hi = s
            flo = prev
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                fm = sign * _poly_slope(S, base, mid)
                if (fm < 0.0) == (flo < 0.0):
                    lo = mid
                    flo = fm
                else:
                    hi = mid
                if hi - lo < 1e-16:
                    break
            if count < DEGREE:
                nodes[count] = 0.5 * (lo + hi)
                count += 1
        prev = cur
    nodes[count] = 1.0
    count += 1
    for i in range(count - 1):
        a = nodes[i]
        b = nodes[i + 1]
        da = sign * (_poly(y0, S, base, a) - level)
        db = sign * (_poly(y0, S, base, b) - level)
        if da >= 0.0 and db < 0.0:
            if da == 0.0:
                return a
            # Illinois (modified regula falsi) on the monotone piece [a, b]
            side = 0
            for _ in range(100):
                s = (a * db - b * da) / (db - da)
                ds = sign * (_poly(y0, S, base, s) - level)
                if ds >= 0.0:
                    a = s
                    da = ds
                    if side == 1:
                        db *= 0.5
                    side = 1
                else:
                    b = s
                    db = ds
                    if side == -1:
                        da *= 0.5
                    side = -1
                if b - a < 1e-15 or ds == 0.0:
                    break
            return s
    return -1.0


@kernel
def _land_theta(t, th, om, target, pr, slide, tc):
    """Henon step: integrate (t, theta') over theta from ``th`` to ``target`` exactly (RK4).

    Used from the dense output at the event, where |target - th| is at the level of the
    integration tolerance, so one step is far more accurate than needed.
    """
    dth = target - th
    if dth == 0.0 or om == 0.0:
        return t, om
    k1t = 1.0 / om
    k1v = rhs(t, th, om, pr, slide, tc) / om
    t2 = t + 0.5 * dth * k1t
    v2 = om + 0.5 * dth * k1v
    k2t = 1.0 / v2
    k2v = rhs(t2, th + 0.5 * dth, v2, pr, slide, tc) / v2
    t3 = t + 0.5 * dth * k2t
    v3 = om + 0.5 * dth * k2v
    k3t = 1.0 / v3
    k3v = rhs(t3, th + 0.5 * dth, v3, pr, slide, tc) / v3
    t4 = t + dth * k3t
    v4 = om + dth * k3v
    k4t = 1.0 / v4
    k4v = rhs(t4, target, v4, pr, slide, tc) / v4
    t_new = t + dth * (k1t + 2.0 * k2t + 2.0 * k3t + k4t) / 6.0
    om_new = om + dth * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
    return t_new, om_new


@kernel
def _land_rest(t, th, om, pr, slide, tc):
    """Henon step with theta' as the independent variable: integrate (t, theta) to theta' = 0."""
    dom = -om
    if dom == 0.0:
        return t, th
    a = rhs(t, th, om, pr, slide, tc)
    if a == 0.0:
        return t, th
    k1t = 1.0 / a
    k1y = om / a
    v2 = om + 0.5 * dom
    t2 = t + 0.5 * dom * k1t
    y2 = th + 0.5 * dom * k1y
    a2 = rhs(t2, y2, v2, pr, slide, tc)
    k2t = 1.0 / a2
    k2y = v2 / a2
    t3 = t + 0.5 * dom * k2t
    y3 = th + 0.5 * dom * k2y
    a3 = rhs(t3, y3, v2, pr, slide, tc)
    k3t = 1.0 / a3
    k3y = v2 / a3
    t4 = t + dom * k3t
    y4 = th + dom * k3y
    a4 = rhs(t4, y4, 0.0, pr, slide, tc)
    k4t = 1.0 / a4
    k4y = 0.0
    t_new = t + dom * (k1t + 2.0 * k2t + 2.0 * k3t + k4t) / 6.0
    th_new = th + dom * (k1y + 2.0 * k2y + 2.0 * k3y + k4y) / 6.0
    return t_new, th_new


@kernel
def _push_event(events, n_events, row):
    """Append one row to the growable event buffer; returns the (possibly new) buffer."""
    if n_events >= events.shape[0]:
        bigger = np.empty((max(16, 2 * events.shape[0]), EV_SIZE))
        bigger[: events.shape[0]] = events
        events = bigger
    events[n_events, :] = row
    return events


@kernel
def _push_dense(dense, n_dense, t, th, om):
    if n_dense >= dense.shape[0]:
        bigger = np.empty((max(1024, 2 * dense.shape[0]), 3))
        bigger[: dense.shape[0]] = dense
        dense = bigger
    dense[n_dense, 0] = t
    dense[n_dense, 1] = th
    dense[n_dense, 2] = om
    return dense


@kernel
def _contact_entry_step(k_contact, om):
    """A fraction of the Hertz contact time at entry speed ``om`` (0 when it has none): the
    force's delta^1.5 onset makes larger first steps fail repeatedly."""
    speed = k_contact[K_SHAFT] * abs(om)
    rate = k_contact[K_SHAFT] * k_contact[K_GAIN] * k_contact[K_STIFFNESS]
    if speed > 0.0 and rate > 0.0:
        return ENTRY_STEP_FRACTION * 3.2181 * (1.0 / (rate * rate * speed)) ** 0.2
    return 0.0


@kernel
def initialise_regions(S, p):
    """Set the contact and sliding flags of S from the state at TB (after a start or restart)."""
    th = S[S_THB]
    om = S[S_OMB]
    thb = p[P.THETA_B]
    contact = p[P.BARRIER] != 0.0 and math.cos(th) > 0.0 and (th > thb or (th == thb and om > 0))
    was_contact = S[S_CONTACT] != 0.0
    S[S_CONTACT] = 1.0 if contact else 0.0
    if contact and not was_contact:
        S[S_ENTRY_T] = S[S_TB]
        S[S_ENTRY_TH] = th
        S[S_ENTRY_OM] = om
        S[S_ENTRY_GRAZE] = 0.0
        S[S_THMAX] = th
        S[S_EXIT_H] = _contact_entry_step(coefficients(p, True), om)
    tc = p[P.COULOMB_ACC]
    if tc > 0.0:
        S[S_SLIDE] = sliding_direction(S[S_TB], th, om, coefficients(p, contact), tc)
        if S[S_SLIDE] == 0.0:
            S[S_STICK_T] = S[S_TB]
    else:
        S[S_SLIDE] = 1.0
    S[S_ACC_OK] = 0.0


@kernel
def new_state(t0, theta0, theta_dot0, p):
    """A fresh integrator state at (t0, theta0, theta_dot0)."""
    S = np.zeros(S_SIZE)
    S[S_TA] = t0
    S[S_TB] = t0
    S[S_THA] = theta0
    S[S_OMA] = theta_dot0
    S[S_THB] = theta0
    S[S_OMB] = theta_dot0
    S[S_H] = -1.0
    initialise_regions(S, p)
    return S


@kernel
def restart(S, t, theta, theta_dot, p):
    """Continue from (t, theta, theta_dot): a new segment start, regions re-evaluated for ``p``."""
    S[S_TA] = t
    S[S_TB] = t
    S[S_THA] = theta
    S[S_OMA] = theta_dot
    S[S_THB] = theta
    S[S_OMB] = theta_dot
    for i in range(2 * DEGREE):
        S[S_POLY + i] = 0.0
    initialise_regions(S, p)


@kernel
def state_at(S, t):
    """(theta, theta') at time t inside the current segment, from its dense output."""
    ta = S[S_TA]
    tb = S[S_TB]
    if tb <= ta:
        return S[S_THB], S[S_OMB]
    s = (t - ta) / (tb - ta)
    return _poly(S[S_THA], S, S_POLY, s), _poly(S[S_OMA], S, S_POLY + DEGREE, s)


@kernel
def _initial_step(t, th, om, a, pr, slide, tc, rtol, atol):
    """Starting step size (Hairer, Norsett & Wanner, section II.4)."""
    sc0 = atol + rtol * abs(th)
    sc1 = atol + rtol * abs(om)
    d0 = math.sqrt(0.5 * ((th / sc0) ** 2 + (om / sc1) ** 2))
    d1 = math.sqrt(0.5 * ((om / sc0) ** 2 + (a / sc1) ** 2))
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    th1 = th + h0 * om
    om1 = om + h0 * a
    a1 = rhs(t + h0, th1, om1, pr, slide, tc)
    d2 = math.sqrt(0.5 * (((om1 - om) / sc0) ** 2 + ((a1 - a) / sc1) ** 2)) / h0
    h1 = max(1e-06, h0 * 0.001) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** 0.125
    return min(100.0 * h0, h1)


@kernel(nogil=True)  # nogil: ensembles run members in threads
def integrate(
    p,
    S,
    out_t,
    out_th,
    out_om,
    pc_t0,
    pc_dt,
    pc_th,
    pc_om,
    t_final,
    rtol,
    atol,
    max_step,
    max_steps,
    events,
    n_events,
    want_dense,
    dense,
    n_dense,
):
    """Integrate from the state S until TB >= t_final and every requested output is written.

    ``out_t`` (increasing, >= current time) receives theta, theta' in ``out_th``,
    ``out_om``; Poincare samples are taken at pc_t0 + k pc_dt, k < len(pc_th).
    Outputs not reached (run stopped early, see S[S_STATUS]) are left as NaN.
    Contact and stick events are appended to ``events`` (grown as needed) and, with
    ``want_dense``, every segment end to ``dense``.  Returns
    (events, n_events, dense, n_dense, outputs written, Poincare samples written).
    """
    tc = p[P.COULOMB_ACC]
    thb = p[P.THETA_B]
    barrier = p[P.BARRIER] != 0.0
    forced = p[P.OMEGA_DRIVE] > 0.0 and (p[P.A1] != 0.0 or p[P.A2] != 0.0)
    period = 2.0 * math.pi / p[P.OMEGA_DRIVE] if p[P.OMEGA_DRIVE] > 0.0 else math.inf
    # A state at rest (on the barrier, undriven) has a zero error estimate, and its step
    # would grow tenfold per step to infinity, past every later output.  No step need be
    # longer than a swing: far beyond any step the error test accepts in motion.
    if p[P.OMEGA2] > 0.0:
        max_step = min(max_step, 2.0 * math.pi / math.sqrt(p[P.OMEGA2]))
    k_contact = coefficients(p, True)
    k_free = coefficients(p, False)
    kth = np.empty(N_EXTENDED)
    kom = np.empty(N_EXTENDED)
    n_out = out_t.shape[0]
    n_pc = pc_th.shape[0]
    gi = 0
    pk = 0
    for j in range(n_out):
        out_th[j] = math.nan
        out_om[j] = math.nan
    for j in range(n_pc):
        pc_th[j] = math.nan
        pc_om[j] = math.nan
    steps_this_call = 0
    row = np.zeros(EV_SIZE)
    # the last step whose stages sit in kth/kom (last_h = 0: none), for its dense output
    last_h = 0.0
    last_t = last_th = last_om = last_th1 = last_om1 = 0.0
    last_pr = k_free
    last_slide = 1.0
    poly_ok = True

    while True:
        # ---- emit outputs that fall inside the current segment [TA, TB]
        ta = S[S_TA]
        tb = S[S_TB]
        need = (gi < n_out and out_t[gi] <= tb) or (pk < n_pc and pc_t0 + pk * pc_dt <= tb)
        if need:
            if not poly_ok:
                _dense_coefficients(
                    last_t,
                    last_th,
                    last_om,
                    last_th1,
                    last_om1,
                    last_h,
                    last_pr,
                    last_slide,
                    tc,
                    kth,
                    kom,
                    S,
                )
                poly_ok = True
            span = tb - ta
            while gi < n_out and out_t[gi] <= tb:
                s = (out_t[gi] - ta) / span if span > 0.0 else 1.0
                out_th[gi] = _poly(S[S_THA], S, S_POLY, s)
                out_om[gi] = _poly(S[S_OMA], S, S_POLY + DEGREE, s)
                gi += 1
            while pk < n_pc and pc_t0 + pk * pc_dt <= tb:
                s = (pc_t0 + pk * pc_dt - ta) / span if span > 0.0 else 1.0
                pc_th[pk] = _poly(S[S_THA], S, S_POLY, s)
                pc_om[pk] = _poly(S[S_OMA], S, S_POLY + DEGREE, s)
                pk += 1
        if gi >= n_out and pk >= n_pc and tb >= t_final:
            break
        if S[S_STATUS] != STATUS_OK:
            break
        if steps_this_call >= max_steps:
            S[S_STATUS] = STATUS_MAX_STEPS
            break

        # ---- next segment, from the state at TB
        t = tb
        th = S[S_THB]
        om = S[S_OMB]
        contact = S[S_CONTACT] != 0.0
        slide = S[S_SLIDE]
        pr = k_contact if contact else k_free

        if slide == 0.0:
            # stuck: theta constant until the other torques exceed the friction torque
            t_release = math.inf
            t_end = max(t_final, t)
            if forced:
                dt_scan = period / STUCK_SCAN_PER_PERIOD
                lo = t
                while lo < t_end:
                    hi = lo + dt_scan
                    if abs(region_acceleration(hi, th, 0.0, pr)) > tc:
                        for _ in range(200):
                            mid = 0.5 * (lo + hi)
                            if mid <= lo or mid >= hi:
                                break
                            if abs(region_acceleration(mid, th, 0.0, pr)) > tc:
                                hi = mid
                            else:
                                lo = mid
                        t_release = hi
                        break
                    lo = hi
                if t_release == math.inf:
                    t_end = lo
            S[S_TA] = t
            S[S_THA] = th
            S[S_OMA] = 0.0
            for i in range(2 * DEGREE):
                S[S_POLY + i] = 0.0
            poly_ok = True
            S[S_ACC_OK] = 0.0
            if t_release < math.inf:
                S[S_TB] = t_release
                a = region_acceleration(t_release, th, 0.0, pr)
                S[S_SLIDE] = 1.0 if a > 0.0 else -1.0
                row[:] = 0.0
                row[EV_KIND] = KIND_STICK
                row[EV_T_IN] = S[S_STICK_T]
                row[EV_TH_IN] = th
                row[EV_T_OUT] = t_release
                row[EV_TH_OUT] = th
                events = _push_event(events, n_events, row)
                n_events += 1
            else:
                S[S_TB] = t_end
            S[S_THB] = th
            S[S_OMB] = 0.0
            if want_dense:
                dense = _push_dense(dense, n_dense, S[S_TB], th, 0.0)
                n_dense += 1
            continue

        a1 = S[S_ACC_B] if S[S_ACC_OK] != 0.0 else rhs(t, th, om, pr, slide, tc)
        h = S[S_H]
        if h <= 0.0:
            h = _initial_step(t, th, om, a1, pr, slide, tc, rtol, atol)
        h = min(h, max_step)
        if contact and om < 0.0 and S[S_EXIT_H] > 0.0:
            # leaving contact: time to the surface at the current deceleration (an
            # underestimate, as the force fades on the way out)
            depth = th - thb
            disc = om * om - 2.0 * a1 * depth
            if depth > 0.0 and disc > 0.0:
                tau = 2.0 * depth / (math.sqrt(disc) - om)
                if EXIT_STEP_FRACTION * tau > S[S_EXIT_H]:
                    h = min(h, EXIT_STEP_FRACTION * tau)
                else:
                    # close enough: cross the surface just beyond the estimated exit, so
                    # that little of the step lies past it (a step reaching far past the
                    # exit has a large error estimate and is rejected, several times); not
                    # below a hundredth of the entry step, where the force is too weak to
                    # matter and tau can fall under the smallest step the clock resolves
                    floor = max(0.01 * S[S_EXIT_H], 10.0 * H_MIN_RELATIVE * max(1.0, abs(t)))
                    h = min(h, max(EXIT_CROSSING_FACTOR * tau, floor))
        # in contact theta' passes through zero at the deepest point, where a test relative
        # to |theta'| alone would ask for atol; its scale there is the entry speed
        om_floor = abs(S[S_ENTRY_OM]) if contact else 0.0
        rejected = False
        while True:
            h_min = H_MIN_RELATIVE * max(1.0, abs(t))
            if h < h_min:
                S[S_STATUS] = STATUS_STEP_UNDERFLOW
                break
            th1, om1, a7, err = _rk_step(
                t, th, om, a1, h, pr, slide, tc, kth, kom, rtol, atol, om_floor
            )
            steps_this_call += 1
            if err <= 1.0:
                break
            S[S_REJECTS] += 1
            rejected = True
            if not err < math.inf:  # NaN or inf
                h *= MIN_FACTOR
            else:
                h *= max(MIN_FACTOR, _step_factor(err))
        if S[S_STATUS] != STATUS_OK:
            break
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, _step_factor(err))
        if rejected:
            factor = min(factor, 1.0)
        h_next = min(h * factor, max_step)
        S[S_STEPS] += 1

        # ---- events inside the accepted step
        last_t, last_th, last_om, last_th1, last_om1, last_h = t, th, om, th1, om1, h
        last_pr = pr
        last_slide = slide
        poly_ok = False
        s_event = 2.0
        kind = 0  # 1: contact surface, 2: theta' = 0
        grazing = False
        if barrier:
            sign = 1.0 if contact else -1.0
            d1 = sign * (th1 - thb)
            if d1 < 0.0 or (sign * om < 0.0 and sign * om1 > 0.0):
                S[S_THA] = th
                S[S_OMA] = om
                _dense_coefficients(t, th, om, th1, om1, h, pr, slide, tc, kth, kom, S)
                poly_ok = True
                s = _first_exit(th, S, S_POLY, thb, sign)
                if s >= 0.0:
                    s_event = s
                    kind = 1
                    grazing = d1 >= 0.0
        if tc > 0.0:
            d1 = slide * om1
            if d1 < 0.0 or (slide * a1 < 0.0 and slide * a7 > 0.0):
                if not poly_ok:
                    S[S_THA] = th
                    S[S_OMA] = om
                    _dense_coefficients(t, th, om, th1, om1, h, pr, slide, tc, kth, kom, S)
                    poly_ok = True
                s = _first_exit(om, S, S_POLY + DEGREE, 0.0, slide)
                if 0.0 <= s < s_event:
                    s_event = s
                    kind = 2

        if kind == 0:
            # plain step
            S[S_TA] = t
            S[S_THA] = th
            S[S_OMA] = om
            S[S_TB] = t + h
            S[S_THB] = th1
            S[S_OMB] = om1
            S[S_ACC_B] = a7
            S[S_ACC_OK] = 1.0
            S[S_H] = h_next
            if contact:
                if th1 > S[S_THMAX]:
                    S[S_THMAX] = th1
                if om > 0.0 and om1 < 0.0:
                    if not poly_ok:
                        _dense_coefficients(t, th, om, th1, om1, h, pr, slide, tc, kth, kom, S)
                        poly_ok = True
                    S[S_THMAX] = max(S[S_THMAX], _poly_max(th, S, S_POLY))
            if abs(th1) > math.pi:
                S[S_STATUS] = STATUS_OVER_THE_TOP
            if want_dense:
                dense = _push_dense(dense, n_dense, t + h, th1, om1)
                n_dense += 1
            continue

        # ---- the state at the event, then one Henon step exactly onto the surface
        S[S_TA] = t
        S[S_THA] = th
        S[S_OMA] = om
        t_land = t + s_event * h
        # the step's dense output, as solve_ivp takes its events
        thl = _poly(th, S, S_POLY, s_event)
        oml = _poly(om, S, S_POLY + DEGREE, s_event)
        entry = kind == 1 and not contact
        if entry and s_event > 0.0 and abs(oml) < SLOW_ENTRY * max(abs(om), abs(om1)):
            # a contact entry sets the whole contact; the dense output's error, about
            # rtol |theta'| of the step, is large against a slow, near-grazing entry speed:
            # there a step of its own (~100x more accurate) is taken instead
            h_land = s_event * h
            thl, oml, _, _ = _rk_step(
                t, th, om, a1, h_land, pr, slide, tc, kth, kom, rtol, atol, om_floor
            )
            S[S_STEPS] += 1
            steps_this_call += 1
            last_th1, last_om1, last_h = thl, oml, h_land
            poly_ok = False
        if kind == 1:
            t_ev, om_ev = _land_theta(t_land, thl, oml, thb, pr, slide, tc)
            th_ev = thb
        else:
            t_ev, th_ev = _land_rest(t_land, thl, oml, pr, slide, tc)
            om_ev = 0.0
        if not (t_ev >= t):  # the Henon correction must not go back past the step start
            t_ev = t_land
        if poly_ok:  # the step's polynomials, restricted to the segment [t, t_ev]
            _rescale_poly(S, (t_ev - t) / h)
        S[S_TB] = t_ev
        S[S_THB] = th_ev
        S[S_OMB] = om_ev
        S[S_ACC_OK] = 0.0
        S[S_H] = max(h_next, 1e-3 * h)
        if contact and s_event > 0.0:
            S[S_THMAX] = max(S[S_THMAX], thl, _poly_max(th, S, S_POLY))
        if want_dense:
            dense = _push_dense(dense, n_dense, t_ev, th_ev, om_ev)
            n_dense += 1
        if kind == 1:
            if contact:
                row[:] = 0.0
                row[EV_KIND] = KIND_CONTACT
                row[EV_T_IN] = S[S_ENTRY_T]
                row[EV_TH_IN] = S[S_ENTRY_TH]
                row[EV_OM_IN] = S[S_ENTRY_OM]
                row[EV_T_OUT] = t_ev
                row[EV_TH_OUT] = th_ev
                row[EV_OM_OUT] = om_ev
                row[EV_DELTA_MAX] = p[P.SHAFT_L] * (math.sin(S[S_THMAX]) - p[P.SIN_THETA_B])
                row[EV_GRAZING] = S[S_ENTRY_GRAZE]
                events = _push_event(events, n_events, row)
                n_events += 1
                S[S_CONTACT] = 0.0
                # free flight resumes from the step size it had before the contact, not from
                # the short contact steps (saves regrowing them, with rejections on the way)
                S[S_H] = max(S[S_H], S[S_FREE_H])
            else:
                S[S_CONTACT] = 1.0
                S[S_ENTRY_T] = t_ev
                S[S_ENTRY_TH] = th_ev
                S[S_ENTRY_OM] = om_ev
                S[S_ENTRY_GRAZE] = 1.0 if grazing else 0.0
                S[S_THMAX] = th_ev
                S[S_FREE_H] = S[S_H]
                h_entry = _contact_entry_step(k_contact, om_ev)
                S[S_EXIT_H] = h_entry
                if h_entry > 0.0:
                    S[S_H] = min(S[S_H], h_entry)
        else:
            new_slide = sliding_direction(t_ev, th_ev, 0.0, pr, tc)
            S[S_SLIDE] = new_slide
            if new_slide == 0.0:
                S[S_STICK_T] = t_ev

    if not poly_ok and last_h > 0.0:
        _dense_coefficients(
            last_t,
            last_th,
            last_om,
            last_th1,
            last_om1,
            last_h,
            last_pr,
            last_slide,
            tc,
            kth,
            kom,
            S,
        )
    return events, n_events, dense, n_dense, gi, pk


@kernel
def _poly_max(y0, S, base):
    """Largest value of the polynomial on [0, 1] (at a root of its slope, or an end)."""
    best = max(y0, _poly(y0, S, base, 1.0))
    samples = 16
    prev = _poly_slope(S, base, 0.0)
    for j in range(1, samples + 1):
        s = j / samples
        cur = _poly_slope(S, base, s)
        if prev > 0.0 >= cur:
            lo = (j - 1) / samples
            hi = s
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if _poly_slope(S, base, mid) > 0.0:
                    lo = mid
                else:
                    hi = mid
                if hi - lo < 1e-16:
                    break
            best = max(best, _poly(y0, S, base, 0.5 * (lo + hi)))
        prev = cur
    return best


@kernel(nogil=True)
def integrate_segments(p, t0, theta0, theta_dot0, out_t, bounds, rtol, atol, max_steps,
                        out_th, out_om, status):
    """Run segment k from (t0[k], theta0[k], theta_dot0[k]) and write theta, theta' at
    out_t[bounds[k]:bounds[k+1]] (its last time is where it ends) and its status code.
    It lives beside ``integrate`` so that numba's cache, which tracks only a kernel's own
    file, is renewed whenever the integrator changes."""
    no_dense = np.empty((0, 3))
    for k in range(t0.shape[0]):
        a = bounds[k]
        b = bounds[k + 1]
        state = new_state(t0[k], theta0[k], theta_dot0[k], p)
        integrate(
            p, state, out_t[a:b], out_th[a:b], out_om[a:b], 0.0, 1.0,
            np.empty(0), np.empty(0), out_t[b - 1], rtol, atol, np.inf, max_steps,
            np.empty((16, EV_SIZE)), 0, False, no_dense, 0,
        )
        status[k] = state[S_STATUS]
