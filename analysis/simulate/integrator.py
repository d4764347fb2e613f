"""Compiled Dormand-Prince 8(5,3) integrator of the impact pendulum with exact event location.

The whole integration loop is one numba function (``integrate``) working on plain
arrays, so a call costs no Python per step; Python callers reach it through a
:class:`Run`, which holds its arguments in named groups (:class:`StepControl`,
:class:`PoincareSamples`, the event buffers).  The non-smooth parts of the model are
handled by splitting the motion into regions, each integrated with a smooth right-hand
side, and by landing exactly on the surfaces between them:

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
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop853

from analysis.model import (
    K_GAIN,
    K_SHAFT,
    K_STIFFNESS,
    coefficients,
    sliding_acceleration,
    sliding_direction,
)
from analysis.packed import P

# Strict IEEE arithmetic, no fast-math flags, not even "contract": with it, LLVM fuses
# a*b + c into an fma wherever the code it is optimising allows, so the rounding depends on
# how a kernel was inlined, and numba links a kernel's helpers from whichever copy the
# process compiled or loaded first (a fresh compile, numba's cache, another kernel's).  The
# same run then gave other numbers in a process that had compiled the integrator than in
# one that loaded it, and maps differed between this process and their workers.
kernel = functools.partial(numba.njit, cache=True)

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
# functions are linked into these kernels (and inlined there by LLVM).  numba's cache
# tracks only a kernel's own file, so after editing the equations in analysis/model.py
# delete this folder's __pycache__ (tests/simulate/test_rhs.py finds a stale cache: the
# kernels' right-hand side then differs from the model's).


@kernel
def rhs(t, th, om, pr, slide, tc):
    """The right-hand side theta'' every step integrates: the model's equation for the
    region's coefficients ``pr`` (contact term or not), sliding in direction ``slide``
    against the friction acceleration ``tc``."""
    return sliding_acceleration(t, th, om, pr, slide, tc)


@kernel(inline="always")  # two call sites; a call would pass ~40 arguments
def _rk_step(t, th, om, a0, h, pr, slide, tc, rtol, atol, om_floor):
    """One DOP853 step: returns theta, theta', theta'' at the end, the scaled error norm
    (Hairer's blend of the 5th- and 3rd-order estimates), with theta' measured relative to
    max(|theta'|, om_floor), and the stages the dense output needs (``_store_stages``).

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
    # the stages the dense output needs: theta' and theta'' of stages 0 and 5-12
    stages = (v0, v5, v6, v7, v8, v9, v10, v11, om1, a0, a5, a6, a7, a8, a9, a10, a11, a12)
    sth = atol + rtol * max(abs(th), abs(th1))
    som = atol + rtol * max(abs(om), abs(om1), om_floor)
    e5 = (e5th / sth) ** 2 + (e5om / som) ** 2
    e3 = (e3th / sth) ** 2 + (e3om / som) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return th1, om1, a12, 0.0, stages
    return th1, om1, a12, abs(h) * e5 / math.sqrt(2.0 * (e5 + 0.01 * e3)), stages


@kernel(inline="always")
def _store_stages(kth, kom, stages):
    """Keep a step's stages (from ``_rk_step``) in kth/kom for its dense output."""
    kth[0], kth[5], kth[6] = stages[0], stages[1], stages[2]
    kth[7], kth[8], kth[9] = stages[3], stages[4], stages[5]
    kth[10], kth[11], kth[12] = stages[6], stages[7], stages[8]
    kom[0], kom[5], kom[6] = stages[9], stages[10], stages[11]
    kom[7], kom[8], kom[9] = stages[12], stages[13], stages[14]
    kom[10], kom[11], kom[12] = stages[15], stages[16], stages[17]


@kernel
def _step_factor(err):
    """The controller's step ratio SAFETY err^(-1/8) for an 8th-order local error (three
    square roots: a pow costs about twice as much, once per step)."""
    return SAFETY / math.sqrt(math.sqrt(math.sqrt(err)))


@kernel
def _dense_coefficients(step, pr, slide, tc, kth, kom, S):
    """Coefficients of the 7th-order dense-output polynomials of ``step`` = (t, theta,
    theta', theta1, theta1', h), into S.

    Needs the step's stages in kth/kom; evaluates the three extra stages of the
    interpolant (only for steps that are sampled or searched for events).
    """
    t, th, om, th1, om1, h = step
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


@kernel(inline="always")
def _slope_root(S, base, sign, lo, hi, flo):
    """The root of the polynomial's slope bracketed by [lo, hi] (slope times ``sign`` is
    ``flo`` at lo), by bisection."""
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
    return 0.5 * (lo + hi)


@kernel(inline="always")
def _monotone_pieces(S, base, sign, nodes):
    """Cut [0, 1] at the polynomial's critical points (roots of its slope, bracketed on a
    grid of 24): the pieces' ends go into ``nodes``, their number is returned."""
    nodes[0] = 0.0
    count = 1
    samples = 24
    prev = sign * _poly_slope(S, base, 0.0)
    for j in range(1, samples + 1):
        s = j / samples
        cur = sign * _poly_slope(S, base, s)
        if (prev < 0.0 <= cur) or (prev > 0.0 >= cur):
            root = _slope_root(S, base, sign, (j - 1) / samples, s, prev)
            if count < DEGREE:
                nodes[count] = root
                count += 1
        prev = cur
    nodes[count] = 1.0
    return count + 1


@kernel(inline="always")
def _illinois(y0, S, base, level, sign, a, b, da, db):
    """The root of d(s) = sign (poly(s) - level) on a monotone piece [a, b] where d goes
    from da > 0 to db < 0, by the Illinois method (modified regula falsi)."""
    side = 0
    s = a
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


@kernel
def _first_exit(y0, S, base, level, sign):
    """First s in [0, 1] where d(s) = sign (poly(s) - level) goes from >= 0 to < 0, else -1.

    The interval is cut at the polynomial's critical points, so d is monotone on each
    piece and an excursion that starts and ends inside the step (grazing) is found as well.
    """
    nodes = np.empty(DEGREE + 2)
    count = _monotone_pieces(S, base, sign, nodes)
    for i in range(count - 1):
        a = nodes[i]
        b = nodes[i + 1]
        da = sign * (_poly(y0, S, base, a) - level)
        db = sign * (_poly(y0, S, base, b) - level)
        if da >= 0.0 and db < 0.0:
            if da == 0.0:
                return a
            return _illinois(y0, S, base, level, sign, a, b, da, db)
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
def _push_dense(dense, n_dense, S):
    """Append the segment end (t, theta, theta') of S to the growable dense record; a record
    of 5 columns also gets the region the motion continues in (contact flag, sliding
    direction), which the sensitivities' replay reads (``variational.REC_*``)."""
    if n_dense >= dense.shape[0]:
        bigger = np.empty((max(1024, 2 * dense.shape[0]), dense.shape[1]))
        bigger[: dense.shape[0]] = dense
        dense = bigger
    dense[n_dense, 0] = S[S_TB]
    dense[n_dense, 1] = S[S_THB]
    dense[n_dense, 2] = S[S_OMB]
    if dense.shape[1] >= 5:
        dense[n_dense, 3] = S[S_CONTACT]
        dense[n_dense, 4] = S[S_SLIDE]
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


# ------------------------------------------------------------------------- the integration loop
# ``integrate`` reads as the loop over segments; its regions are the helpers below, which
# numba inlines (inline="always": compiled as if written out in the loop; called instead,
# the rarer ones cost 3 % of the run).  An array passed to an inlined helper is a new
# reference that numba counts (two atomic operations per array and pass, about 1 % of a
# step each) unless the helper uses it in straight-line code: so on the path of every step
# the helpers that branch take scalars and those that take arrays do not branch; only the
# rarer paths (a step with an event or a search of its dense output, a stuck interval)
# pass arrays to helpers that branch.


@kernel(inline="always")
def _longest_step(max_step, omega2):
    """The step cap: at most ``max_step``, and never longer than a swing.  A state at rest
    (on the barrier, undriven) has a zero error estimate, and its step would grow tenfold
    per step to infinity, past every later output; no step in motion comes near a swing."""
    if omega2 > 0.0:
        return min(max_step, 2.0 * math.pi / math.sqrt(omega2))
    return max_step


@kernel(inline="always")
def _final_dense(poly_ok, step, pr, slide, tc, kth, kom, S):
    """At the end of a call, the dense output of the last step into S (the segment a
    streaming caller continues from), unless it is there already or there was no step."""
    if poly_ok or not step[5] > 0.0:
        return
    _dense_coefficients(step, pr, slide, tc, kth, kom, S)


@kernel(inline="always")
def _segment_fraction(t, ta, span):
    """Where t lies in the current segment [ta, ta + span], as a fraction (1 if it has none)."""
    return (t - ta) / span if span > 0.0 else 1.0


@kernel(inline="always")
def _dense_state(S, s):
    """(theta, theta') at fraction s of the current segment, from its dense output."""
    return _poly(S[S_THA], S, S_POLY, s), _poly(S[S_OMA], S, S_POLY + DEGREE, s)


@kernel(inline="always")
def _run_status(status, finished, steps_this_call, max_steps):
    """(stop, status): the loop stops when every output is written or the run stopped, and
    with status max_steps when this call's step budget is spent."""
    if finished or status != STATUS_OK:
        return True, status
    if steps_this_call >= max_steps:
        return True, STATUS_MAX_STEPS
    return False, status


@kernel(inline="always")
def _release_time(t, t_end, th, pr, tc, period):
    """First time after t when the other torques exceed the friction torque, scanned at
    STUCK_SCAN_PER_PERIOD points per drive period and bisected; (inf, end of the scan) when
    they do not before t_end."""
    dt_scan = period / STUCK_SCAN_PER_PERIOD
    lo = t
    while lo < t_end:
        hi = lo + dt_scan
        if sliding_direction(hi, th, 0.0, pr, tc) != 0.0:
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if sliding_direction(mid, th, 0.0, pr, tc) != 0.0:
                    hi = mid
                else:
                    lo = mid
            return hi, t_end
        lo = hi
    return math.inf, lo


@kernel(inline="always")
def _stuck_segment(S, t, th, pr, tc, forced, period, t_final, events, n_events, row):
    """Stuck: theta constant until the other torques exceed the friction torque (never,
    undriven).  The segment ends at the release (a stick event, sliding resumes) or at
    t_final; returns the event buffer and count."""
    t_release = math.inf
    t_end = max(t_final, t)
    if forced:
        t_release, t_end = _release_time(t, t_end, th, pr, tc, period)
    S[S_TA] = t
    S[S_THA] = th
    S[S_OMA] = 0.0
    for i in range(2 * DEGREE):
        S[S_POLY + i] = 0.0
    S[S_ACC_OK] = 0.0
    S[S_TB] = t_end
    if t_release < math.inf:
        S[S_TB] = t_release
        S[S_SLIDE] = sliding_direction(t_release, th, 0.0, pr, tc)
        row[:] = 0.0
        row[EV_KIND] = KIND_STICK
        row[EV_T_IN] = S[S_STICK_T]
        row[EV_TH_IN] = th
        row[EV_T_OUT] = t_release
        row[EV_TH_OUT] = th
        events = _push_event(events, n_events, row)
        n_events += 1
    S[S_THB] = th
    S[S_OMB] = 0.0
    return events, n_events


@kernel(inline="always")
def _exit_approach_step(h, exit_h, t, th, om, a1, thb):
    """The step size leaving contact: a fraction of the time to the surface at the current
    deceleration (an underestimate, as the force fades on the way out); ``exit_h`` is the
    shortest step of the approach."""
    depth = th - thb
    disc = om * om - 2.0 * a1 * depth
    if depth > 0.0 and disc > 0.0:
        tau = 2.0 * depth / (math.sqrt(disc) - om)
        if EXIT_STEP_FRACTION * tau > exit_h:
            return min(h, EXIT_STEP_FRACTION * tau)
        # close enough: cross the surface just beyond the estimated exit, so that little
        # of the step lies past it (a step reaching far past the exit has a large error
        # estimate and is rejected, several times); not below a hundredth of the entry
        # step, where the force is too weak to matter and tau can fall under the smallest
        # step the clock resolves
        floor = max(0.01 * exit_h, 10.0 * H_MIN_RELATIVE * max(1.0, abs(t)))
        return min(h, max(EXIT_CROSSING_FACTOR * tau, floor))
    return h


@kernel(inline="always")
def _trial_step_size(proposed, exit_h, t, th, om, a1, contact, thb, max_step, pr, slide, tc,
                     rtol, atol):
    """The size of the next step to try: the controller's ``proposed`` one (a fresh one when
    <= 0), capped, and shortened on the way out of a contact (``exit_h`` > 0)."""
    h = proposed
    if h <= 0.0:
        h = _initial_step(t, th, om, a1, pr, slide, tc, rtol, atol)
    h = min(h, max_step)
    if contact and om < 0.0 and exit_h > 0.0:
        h = _exit_approach_step(h, exit_h, t, th, om, a1, thb)
    return h


@kernel(inline="always")
def _accepted_step(t, th, om, a1, h, pr, slide, tc, rtol, atol, om_floor):
    """Try steps from (t, theta, theta'), shrinking h after each rejection, until one passes
    the error test or h underflows.  Returns theta, theta', theta'' at its end, its error,
    its size, its stages, the steps tried, the rejections and whether one was accepted."""
    th1 = om1 = a7 = err = 0.0
    stages = (0.0,) * 18
    tried = 0
    rejects = 0
    accepted = False
    while not accepted:
        if h < H_MIN_RELATIVE * max(1.0, abs(t)):
            break
        th1, om1, a7, err, stages = _rk_step(
            t, th, om, a1, h, pr, slide, tc, rtol, atol, om_floor
        )
        tried += 1
        accepted = err <= 1.0
        if not accepted:
            rejects += 1
            h *= MIN_FACTOR if not err < math.inf else max(MIN_FACTOR, _step_factor(err))
    return th1, om1, a7, err, h, stages, tried, rejects, accepted


@kernel(inline="always")
def _next_step_size(h, err, rejected, max_step):
    """The controller's proposal after an accepted step (no growth right after a rejection)."""
    factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, _step_factor(err))
    if rejected:
        factor = min(factor, 1.0)
    return min(h * factor, max_step)


@kernel(inline="always")
def _may_cross(step, a1, a7, slide, tc, barrier, contact, thb):
    """What the step's dense output must be searched for: a crossing of the contact surface
    (the step ends beyond it, or an extremum of it may lie beyond: grazing), theta' reaching
    0 against friction, and in contact the deepest point (theta' from + to -)."""
    _, _, om, th1, om1, _ = step
    sign = 1.0 if contact else -1.0
    surface = barrier and (sign * (th1 - thb) < 0.0 or (sign * om < 0.0 and sign * om1 > 0.0))
    rest = tc > 0.0 and (slide * om1 < 0.0 or (slide * a1 < 0.0 and slide * a7 > 0.0))
    deepest = contact and om > 0.0 and om1 < 0.0
    return surface, rest, deepest


@kernel(inline="always")
def _search_step(S, step, pr, slide, tc, kth, kom, surface, rest, deepest, contact, thb):
    """Search an accepted step's dense output (computed into S) for its first event:
    (fraction of the step, kind 0 none, 1 contact surface, 2 theta' = 0 under friction,
    grazing: the step ends on the side it began).  Without an event, the deepest point
    inside a contact step counts for the contact's largest penetration."""
    _, th, om, th1, _, _ = step
    S[S_THA] = th
    S[S_OMA] = om
    _dense_coefficients(step, pr, slide, tc, kth, kom, S)
    s_event = 2.0
    kind = 0
    grazing = False
    sign = 1.0 if contact else -1.0
    if surface:
        s = _first_exit(th, S, S_POLY, thb, sign)
        if s >= 0.0:
            s_event = s
            kind = 1
            grazing = sign * (th1 - thb) >= 0.0
    if rest:
        s = _first_exit(om, S, S_POLY + DEGREE, 0.0, slide)
        if 0.0 <= s < s_event:
            s_event = s
            kind = 2
    if deepest and kind == 0:
        S[S_THMAX] = max(S[S_THMAX], _poly_max(th, S, S_POLY))
    return s_event, kind, grazing


@kernel(inline="always")
def _deepest_so_far(thmax, th1, contact):
    """The contact's deepest angle after a step ending at th1 (unchanged in free flight)."""
    return th1 if contact and th1 > thmax else thmax


@kernel(inline="always")
def _status_after(status, th1):
    """The run's status after a step ending at th1: over_the_top beyond pi."""
    return STATUS_OVER_THE_TOP if abs(th1) > math.pi else status


@kernel(inline="always")
def _plain_step(S, step, a7, h_next, thmax, status):
    """An accepted step without event becomes the current segment."""
    t, th, om, th1, om1, h = step
    S[S_TA] = t
    S[S_THA] = th
    S[S_OMA] = om
    S[S_TB] = t + h
    S[S_THB] = th1
    S[S_OMB] = om1
    S[S_ACC_B] = a7
    S[S_ACC_OK] = 1.0
    S[S_H] = h_next
    S[S_THMAX] = thmax
    S[S_STATUS] = status


@kernel(inline="always")
def _slow_entry(s_event, kind, contact, om_event, om, om1):
    """A contact entry sets the whole contact; the dense output's error, about rtol |theta'|
    of the step, is large against a slow, near-grazing entry speed: there a step of its own
    (~100x more accurate) is taken to the event instead."""
    entry = kind == 1 and not contact
    return entry and s_event > 0.0 and abs(om_event) < SLOW_ENTRY * max(abs(om), abs(om1))


@kernel(inline="always")
def _land(t, t_land, thl, oml, kind, thb, pr, slide, tc):
    """One Henon step from the state near the event exactly onto its surface: theta = theta_b
    (kind 1) or theta' = 0 (kind 2), not back past the step's start t.  Returns
    (t, theta, theta') there."""
    if kind == 1:
        t_ev, om_ev = _land_theta(t_land, thl, oml, thb, pr, slide, tc)
        th_ev = thb
    else:
        t_ev, th_ev = _land_rest(t_land, thl, oml, pr, slide, tc)
        om_ev = 0.0
    if not (t_ev >= t):
        t_ev = t_land
    return t_ev, th_ev, om_ev


@kernel(inline="always")
def _event_segment(S, t, th, h, h_next, s_event, thl, event, poly_ok, contact):
    """The current segment ends at the event (t, theta, theta'): the step's polynomials are
    restricted to it, and the next step starts from the event."""
    t_ev, th_ev, om_ev = event
    if poly_ok:  # the step's polynomials, restricted to the segment [t, t_ev]
        _rescale_poly(S, (t_ev - t) / h)
    S[S_TB] = t_ev
    S[S_THB] = th_ev
    S[S_OMB] = om_ev
    S[S_ACC_OK] = 0.0
    S[S_H] = max(h_next, 1e-3 * h)
    if contact and s_event > 0.0:
        S[S_THMAX] = max(S[S_THMAX], thl, _poly_max(th, S, S_POLY))


@kernel(inline="always")
def _leave_contact(S, p, event, events, n_events, row):
    """The contact ends at ``event``: record it; free flight resumes from the step size it
    had before the contact, not from the short contact steps (saves regrowing them, with
    rejections on the way).  Returns the event buffer and count."""
    t_ev, th_ev, om_ev = event
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
    S[S_CONTACT] = 0.0
    S[S_H] = max(S[S_H], S[S_FREE_H])
    return events, n_events + 1


@kernel(inline="always")
def _enter_contact(S, event, grazing, k_contact):
    """A contact begins at ``event``: remember its entry, and start it with a short step."""
    t_ev, th_ev, om_ev = event
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


@kernel(inline="always")
def _change_region(S, p, kind, contact, grazing, event, pr, tc, k_contact, events, n_events,
                   row):
    """Pass into the region beyond the event: out of or into contact (kind 1), stuck or
    sliding on from theta' = 0 (kind 2).  Returns the event buffer and count."""
    if kind == 1 and contact:
        return _leave_contact(S, p, event, events, n_events, row)
    if kind == 1:
        _enter_contact(S, event, grazing, k_contact)
        return events, n_events
    t_ev, th_ev, _ = event
    S[S_SLIDE] = sliding_direction(t_ev, th_ev, 0.0, pr, tc)
    if S[S_SLIDE] == 0.0:
        S[S_STICK_T] = t_ev
    return events, n_events


@kernel(inline="always")
def _event_step(S, p, step, a1, h_next, s_event, kind, grazing, contact, pr, slide, tc,
                k_contact, kth, kom, rtol, atol, om_floor, events, n_events, row):
    """An accepted step with an event (its dense output in S) ends the segment there: the
    state at the event (from the dense output, or a step of its own for a slow entry), one
    Henon step exactly onto the surface, then the region beyond it.  Returns the event
    buffer and count, the last step, whether its dense output is in S, and the extra steps
    taken."""
    t, th, om, _, om1, h = step
    S[S_TA] = t
    S[S_THA] = th
    S[S_OMA] = om
    # the step's dense output, as solve_ivp takes its events
    thl = _poly(th, S, S_POLY, s_event)
    oml = _poly(om, S, S_POLY + DEGREE, s_event)
    # the event's time on the step; a slow entry below takes a step of that length
    t_land = t + s_event * h
    poly_ok = True
    extra = 0
    if _slow_entry(s_event, kind, contact, oml, om, om1):
        h_land = s_event * h
        thl, oml, _, _, stages = _rk_step(
            t, th, om, a1, h_land, pr, slide, tc, rtol, atol, om_floor
        )
        _store_stages(kth, kom, stages)
        S[S_STEPS] += 1
        extra = 1
        step = (t, th, om, thl, oml, h_land)
        poly_ok = False
    event = _land(t, t_land, thl, oml, kind, p[P.THETA_B], pr, slide, tc)
    _event_segment(S, t, th, h, h_next, s_event, thl, event, poly_ok, contact)
    events, n_events = _change_region(
        S, p, kind, contact, grazing, event, pr, tc, k_contact, events, n_events, row
    )
    return events, n_events, step, poly_ok, extra


# C901 (12 > 10): the loop keeps in itself the branches that pass arrays on the path of
# every step (writing the outputs, a stuck or a moving segment, the step's outcome, the dense
# record): moved into helpers they would cost a few % of the run (see above).  Each branch
# is a line or two that names its helper.
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
    Python calls it through :meth:`Run.advance`, which names these arguments' groups.

    ``out_t`` (increasing, >= current time) receives theta, theta' in ``out_th``,
    ``out_om``; Poincare samples are taken at pc_t0 + k pc_dt, k < len(pc_th).
    Outputs not reached (run stopped early, see S[S_STATUS]) are left as NaN.
    Contact and stick events are appended to ``events`` (grown as needed) and, with
    ``want_dense``, every segment end to ``dense`` (given 5 columns, with the region it leads
    into: ``_push_dense``).  Returns
    (events, n_events, dense, n_dense, outputs written, Poincare samples written).
    """
    tc = p[P.COULOMB_ACC]
    thb = p[P.THETA_B]
    barrier = p[P.BARRIER] != 0.0
    forced = p[P.OMEGA_DRIVE] > 0.0 and (p[P.A1] != 0.0 or p[P.A2] != 0.0)
    period = 2.0 * math.pi / p[P.OMEGA_DRIVE] if p[P.OMEGA_DRIVE] > 0.0 else math.inf
    max_step = _longest_step(max_step, p[P.OMEGA2])
    k_contact = coefficients(p, True)
    k_free = coefficients(p, False)
    kth = np.empty(N_EXTENDED)
    kom = np.empty(N_EXTENDED)
    n_out = out_t.shape[0]
    n_pc = pc_th.shape[0]
    gi = 0
    pk = 0
    out_th[:] = math.nan
    out_om[:] = math.nan
    pc_th[:] = math.nan
    pc_om[:] = math.nan
    steps_this_call = 0
    row = np.zeros(EV_SIZE)
    # the last step (t, theta, theta', theta1, theta1', h; h = 0: none) whose stages sit in
    # kth/kom, for its dense output, and its region
    last = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    last_pr = k_free
    last_slide = 1.0
    poly_ok = True

    while True:
        # ---- the outputs inside the current segment [TA, TB], from its dense output
        ta = S[S_TA]
        tb = S[S_TB]
        if (gi < n_out and out_t[gi] <= tb) or (pk < n_pc and pc_t0 + pk * pc_dt <= tb):
            if not poly_ok:
                _dense_coefficients(last, last_pr, last_slide, tc, kth, kom, S)
                poly_ok = True
            while gi < n_out and out_t[gi] <= tb:
                out_th[gi], out_om[gi] = _dense_state(S, _segment_fraction(out_t[gi], ta, tb - ta))
                gi += 1
            while pk < n_pc and pc_t0 + pk * pc_dt <= tb:
                s = _segment_fraction(pc_t0 + pk * pc_dt, ta, tb - ta)
                pc_th[pk], pc_om[pk] = _dense_state(S, s)
                pk += 1
        finished = gi >= n_out and pk >= n_pc and tb >= t_final
        stop, S[S_STATUS] = _run_status(S[S_STATUS], finished, steps_this_call, max_steps)
        if stop:
            break

        # ---- the next segment, from the state at TB
        t = tb
        th = S[S_THB]
        om = S[S_OMB]
        contact = S[S_CONTACT] != 0.0
        slide = S[S_SLIDE]
        pr = k_contact if contact else k_free
        if slide == 0.0:
            events, n_events = _stuck_segment(
                S, t, th, pr, tc, forced, period, t_final, events, n_events, row
            )
            poly_ok = True
        else:
            a1 = S[S_ACC_B] if S[S_ACC_OK] != 0.0 else rhs(t, th, om, pr, slide, tc)
            h = _trial_step_size(
                S[S_H], S[S_EXIT_H], t, th, om, a1, contact, thb, max_step, pr, slide, tc,
                rtol, atol,
            )
            # in contact theta' passes through zero at the deepest point, where a test
            # relative to |theta'| alone would ask for atol; its scale there is the entry speed
            om_floor = abs(S[S_ENTRY_OM]) if contact else 0.0
            th1, om1, a7, err, h, stages, tried, rejects, accepted = _accepted_step(
                t, th, om, a1, h, pr, slide, tc, rtol, atol, om_floor
            )
            steps_this_call += tried
            S[S_REJECTS] += rejects
            if not accepted:
                S[S_STATUS] = STATUS_STEP_UNDERFLOW
                break
            _store_stages(kth, kom, stages)
            h_next = _next_step_size(h, err, rejects > 0, max_step)
            S[S_STEPS] += 1
            last = (t, th, om, th1, om1, h)
            last_pr = pr
            last_slide = slide

            # ---- events inside the accepted step
            surface, rest, deepest = _may_cross(last, a1, a7, slide, tc, barrier, contact, thb)
            s_event, kind, grazing = 2.0, 0, False
            poly_ok = surface or rest or deepest
            if poly_ok:
                s_event, kind, grazing = _search_step(
                    S, last, pr, slide, tc, kth, kom, surface, rest, deepest, contact, thb
                )
            if kind == 0:
                thmax = _deepest_so_far(S[S_THMAX], th1, contact)
                _plain_step(S, last, a7, h_next, thmax, _status_after(S[S_STATUS], th1))
            else:
                events, n_events, last, poly_ok, extra = _event_step(
                    S, p, last, a1, h_next, s_event, kind, grazing, contact, pr, slide, tc,
                    k_contact, kth, kom, rtol, atol, om_floor, events, n_events, row,
                )
                steps_this_call += extra
        if want_dense:
            dense = _push_dense(dense, n_dense, S)
            n_dense += 1

    _final_dense(poly_ok, last, last_pr, last_slide, tc, kth, kom, S)
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
    # typed, not literal, so that this call shares the compiled ``integrate`` that
    # ``Run.advance`` calls (literal 0 and False arguments compile a second copy: 28 s cold);
    # the one call besides it that spells the kernel's arguments (compiled code cannot
    # call a Python method)
    none_yet = np.int64(0)
    no_dense_wanted = np.bool_(False)
    for k in range(t0.shape[0]):
        a = bounds[k]
        b = bounds[k + 1]
        state = new_state(t0[k], theta0[k], theta_dot0[k], p)
        integrate(
            p, state, out_t[a:b], out_th[a:b], out_om[a:b], 0.0, 1.0,
            np.empty(0), np.empty(0), out_t[b - 1], rtol, atol, np.inf, max_steps,
            np.empty((16, EV_SIZE)), none_yet, no_dense_wanted, no_dense, none_yet,
        )
        status[k] = state[S_STATUS]


# ----------------------------------------------------------------------------- the Python entry
# The kernel takes its arguments as plain arrays and numbers: numba passes those at a fraction
# of a microsecond each, while a tuple or a structure is boxed field by field on every call
# (13-19 % of a Stepper's 10 ms chunk at 200 kHz).  Python callers hold a run's arguments in
# a ``Run`` instead, whose ``advance`` alone spells the kernel's 19 positions.  A method of
# an object the streaming caller keeps adds ~1.5 % to that chunk (the old 19-argument call
# against this one in one process); named groups built anew on each call added 5-7 %.

DEFAULT_MAX_STEPS = 200_000_000


@dataclass(frozen=True, slots=True)
class StepControl:
    """How a run steps: the error tolerances ``rtol``, ``atol``, the longest step
    ``max_step`` [s] (inf: no cap) and the most steps one call may take (then the run stops
    with status max_steps).  Kept as float and int: other types would compile another copy
    of the kernel."""

    rtol: float
    atol: float
    max_step: float = math.inf
    max_steps: int = DEFAULT_MAX_STEPS

    def __post_init__(self) -> None:
        object.__setattr__(self, "rtol", float(self.rtol))
        object.__setattr__(self, "atol", float(self.atol))
        object.__setattr__(self, "max_step", float(self.max_step))
        object.__setattr__(self, "max_steps", int(self.max_steps))


class PoincareSamples(NamedTuple):
    """Samples at t0 + k dt, k < len(theta), into ``theta``, ``theta_dot``."""

    t0: float
    dt: float
    theta: np.ndarray
    theta_dot: np.ndarray


NO_POINCARE = PoincareSamples(0.0, 1.0, np.empty(0), np.empty(0))
_NO_DENSE = np.empty((0, 3))


class Run:
    """A run of the integrator: the packed vector ``p``, the state it advances in place
    (``new_state``; ``restart`` or a new one between calls is the caller's), how it steps,
    where its Poincare samples go, and the rows it appends, grown as needed: contact and
    stick events (``events[:n_events]``, columns ``EV_*``) and, with ``dense_columns``
    (3: t, theta, theta'; 5 with the region it leads into, for the sensitivities), every
    segment end (``dense[:n_dense]``).  A caller reusing it for a new start sets ``state``
    and the counts back; ``poincare_written`` counts the Poincare samples of the last call.
    """

    __slots__ = (
        "control", "dense", "events", "n_dense", "n_events", "p", "poincare",
        "poincare_written", "state",
    )

    def __init__(
        self,
        p: np.ndarray,
        state: np.ndarray,
        control: StepControl,
        poincare: PoincareSamples = NO_POINCARE,
        dense_columns: int = 0,
    ) -> None:
        self.p = p
        self.state = state
        self.control = control
        self.poincare = poincare
        self.events = np.empty((16, EV_SIZE))
        self.n_events = 0
        self.dense = np.empty((1024, dense_columns)) if dense_columns else None
        self.n_dense = 0
        self.poincare_written = 0

    def advance(
        self, t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray, t_end: float
    ) -> int:
        """Integrate until ``t_end`` and every sample asked for is reached: theta, theta'
        at the increasing times ``t`` (not before the state's time) into ``theta``,
        ``theta_dot``, and the Poincare samples; NaN where the run stopped early (the
        state's S_STATUS says why).  Returns how many samples were written."""
        c = self.control
        pc = self.poincare
        dense = self.dense
        want_dense = dense is not None
        self.events, self.n_events, dense, n_dense, written, self.poincare_written = integrate(
            self.p, self.state, t, theta, theta_dot, pc.t0, pc.dt, pc.theta, pc.theta_dot,
            t_end, c.rtol, c.atol, c.max_step, c.max_steps, self.events, self.n_events,
            want_dense, dense if want_dense else _NO_DENSE, self.n_dense,
        )
        if want_dense:
            self.dense = dense
            self.n_dense = n_dense
        return written
