"""Compiled Dormand-Prince 5(4) integrator of the impact pendulum with exact event location.

The whole integration loop is one numba function (``integrate``) working on plain
arrays, so a call costs no Python per step.  The non-smooth parts of the model are
handled by splitting the motion into regions, each integrated with a smooth
right-hand side, and by landing exactly on the surfaces between them:

* free flight / contact: the contact surface theta = theta_b.  A step that crosses
  it (sign change of theta - theta_b at its end) or grazes it (an extremum of the
  step's dense-output polynomial beyond the surface, the case a sign test misses)
  is cut at the first crossing found on the dense output; a landing step of that
  length is taken and one Henon step (theta as the independent variable) puts the
  state exactly on the surface.
* Coulomb friction: sliding in a fixed direction until theta' = 0 (located the same
  way, landed with theta' as the independent variable), then stuck while the other
  torques stay within the friction torque; the release time is located on the
  (time-only) acceleration function.

The integrator keeps its state in a small float vector (layout ``S_*``) so that a
streaming caller can continue a run across calls; the last step's dense-output
polynomial stays valid, so outputs at any time inside it cost a few flops.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from analysis.model import P

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

S_TA = 0  # start time of the current segment (step, landing step or stuck interval)
S_TB = 1  # its end time: the integrator's own "now"
S_THA = 2  # theta at TA
S_OMA = 3  # theta' at TA
S_THB = 4  # theta at TB
S_OMB = 5  # theta' at TB
S_POLY = 6  # 8 dense-output coefficients: theta(s) = THA + c0 s + .. + c3 s^4, theta'(s) likewise
S_H = 14  # next step size proposal (<= 0: choose one)
S_CONTACT = 15  # 1.0 while theta > theta_b (in contact), else 0.0
S_SLIDE = 16  # Coulomb sliding direction +1 / -1, 0 stuck (always +1 without friction)
S_STATUS = 17
S_ENTRY_T = 18  # current contact: entry time, theta, theta', grazing flag, max theta so far
S_ENTRY_TH = 19
S_ENTRY_OM = 20
S_ENTRY_GRAZE = 21
S_THMAX = 22
S_STEPS = 23  # accepted steps (landing steps included)
S_REJECTS = 24
S_STICK_T = 25  # start of the current stuck interval
S_ACC_B = 26  # theta'' at TB (first-same-as-last stage), valid when S_ACC_OK = 1
S_ACC_OK = 27
S_SIZE = 28

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

# ----------------------------------------------------------------------------- Dormand-Prince 5(4)

C2, C3, C4, C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0
A21 = 1.0 / 5.0
A31, A32 = 3.0 / 40.0, 9.0 / 40.0
A41, A42, A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
A51, A52, A53, A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
A61, A62, A63, A64, A65 = (
    9017.0 / 3168.0,
    -355.0 / 33.0,
    46732.0 / 5247.0,
    49.0 / 176.0,
    -5103.0 / 18656.0,
)
B1, B3, B4, B5, B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
# error weights: 5th-order minus embedded 4th-order solution
E1, E3, E4, E5, E6, E7 = (
    71.0 / 57600.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
)
# dense output (4th order): y(s) = y0 + h sum_k K_k (Q_k1 s + Q_k2 s^2 + Q_k3 s^3 + Q_k4 s^4)
Q11, Q12, Q13, Q14 = 1.0, -2.8535800653862835, 3.0717434641059005, -1.1270175653862835
Q32, Q33, Q34 = 4.023133379230305, -6.249321565289, 2.675424484351598
Q42, Q43, Q44 = -3.7324019615885042, 10.068970589843675, -5.685526961588504
Q52, Q53, Q54 = 2.5548038301849423, -6.399112377351017, 3.5219323679207912
Q62, Q63, Q64 = -1.3744241142186024, 3.272657752246729, -1.7672812570757455
Q72, Q73, Q74 = 1.3824689317781436, -3.764937863556287, 2.382468931778144

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 5.0
STUCK_SCAN_PER_PERIOD = 128  # release search resolution while stuck under forcing


# ----------------------------------------------------------------------------- right-hand side
# The kernel evaluates analysis.model.smooth_acceleration with the packed vector's entries
# hoisted into a tuple of scalars once per call, sin/cos of theta taken once per stage, the
# drive's second harmonic and the general power law skipped when they are off.  The terms
# are exactly those of analysis.model (tests/simulate/test_rhs.py checks equality over
# random packed vectors); the physics is defined there, not here.

K_OMEGA2, K_TWO_ZETA_OMEGA, K_C2, K_INV_L, K_OMEGA_DRIVE, K_PHASE0 = 0, 1, 2, 3, 4, 5
K_A1, K_A2, K_PHI2, K_GAIN, K_SHAFT, K_STIFFNESS, K_EXPONENT = 6, 7, 8, 9, 10, 11, 12
K_MU0, K_C_VISCOUS, K_SIN_THETA_B, K_CONTACT_ON, K_HERTZ, K_FORCED, K_HARMONIC2 = (
    13,
    14,
    15,
    16,
    17,
    18,
    19,
)


@numba.njit(cache=True)
def coefficients(p, contact):
    """The packed vector as a tuple of scalars for the kernel; ``contact`` False drops the
    barrier term (free-flight region)."""
    forced = p[P.OMEGA_DRIVE] != 0.0 and (p[P.A1] != 0.0 or p[P.A2] != 0.0)
    return (
        p[P.OMEGA2],
        p[P.TWO_ZETA_OMEGA],
        p[P.C2],
        p[P.INV_L],
        p[P.OMEGA_DRIVE],
        p[P.PHASE0],
        p[P.A1],
        p[P.A2],
        p[P.PHI2],
        p[P.CONTACT_GAIN],
        p[P.SHAFT_L],
        p[P.K],
        p[P.EXPONENT],
        p[P.MU0],
        p[P.C_VISCOUS],
        p[P.SIN_THETA_B],
        1.0 if (contact and p[P.BARRIER] != 0.0) else 0.0,
        1.0 if p[P.EXPONENT] == 1.5 else 0.0,
        1.0 if forced else 0.0,
        1.0 if p[P.A2] != 0.0 else 0.0,
    )


@numba.njit(cache=True, inline="always")
def region_acceleration(t, th, om, k):
    """analysis.model.smooth_acceleration for the coefficient tuple ``k`` (see above)."""
    s = math.sin(th)
    c = math.cos(th)
    acc = -k[K_TWO_ZETA_OMEGA] * om - k[K_C2] * om * abs(om) - k[K_OMEGA2] * s
    if k[K_FORCED] != 0.0:
        w = k[K_OMEGA_DRIVE]
        phase = w * t + k[K_PHASE0]
        drive = k[K_A1] * math.sin(phase)
        if k[K_HARMONIC2] != 0.0:
            drive += 4.0 * k[K_A2] * math.sin(2.0 * phase + k[K_PHI2])
        acc += w * w * drive * k[K_INV_L] * c
    if k[K_CONTACT_ON] != 0.0 and c > 0.0:
        delta = k[K_SHAFT] * (s - k[K_SIN_THETA_B])
        if delta > 0.0:
            delta_dot = k[K_SHAFT] * c * om
            power = delta * math.sqrt(delta) if k[K_HERTZ] != 0.0 else delta ** k[K_EXPONENT]
            force = k[K_STIFFNESS] * power * (1.0 + k[K_MU0] * delta_dot)
            force += k[K_C_VISCOUS] * delta_dot
            if force > 0.0:
                acc -= k[K_GAIN] * force
    return acc


@numba.njit(cache=True, inline="always")
def _acc(t, th, om, pr, slide, tc):
    """theta'' of the current region: smooth terms plus friction in a fixed direction."""
    return region_acceleration(t, th, om, pr) - slide * tc


@numba.njit(cache=True, inline="always")
def _dopri_step(t, th, om, a1, h, pr, slide, tc, kth, kom):
    """One Dormand-Prince step: fills the stage slopes; returns theta, theta', a7 and errors."""
    kth[0] = om
    kom[0] = a1
    y = th + h * A21 * om
    v = om + h * A21 * a1
    kth[1] = v
    kom[1] = _acc(t + C2 * h, y, v, pr, slide, tc)
    y = th + h * (A31 * kth[0] + A32 * kth[1])
    v = om + h * (A31 * kom[0] + A32 * kom[1])
    kth[2] = v
    kom[2] = _acc(t + C3 * h, y, v, pr, slide, tc)
    y = th + h * (A41 * kth[0] + A42 * kth[1] + A43 * kth[2])
    v = om + h * (A41 * kom[0] + A42 * kom[1] + A43 * kom[2])
    kth[3] = v
    kom[3] = _acc(t + C4 * h, y, v, pr, slide, tc)
    y = th + h * (A51 * kth[0] + A52 * kth[1] + A53 * kth[2] + A54 * kth[3])
    v = om + h * (A51 * kom[0] + A52 * kom[1] + A53 * kom[2] + A54 * kom[3])
    kth[4] = v
    kom[4] = _acc(t + C5 * h, y, v, pr, slide, tc)
    y = th + h * (A61 * kth[0] + A62 * kth[1] + A63 * kth[2] + A64 * kth[3] + A65 * kth[4])
    v = om + h * (A61 * kom[0] + A62 * kom[1] + A63 * kom[2] + A64 * kom[3] + A65 * kom[4])
    kth[5] = v
    kom[5] = _acc(t + h, y, v, pr, slide, tc)
    th1 = th + h * (B1 * kth[0] + B3 * kth[2] + B4 * kth[3] + B5 * kth[4] + B6 * kth[5])
    om1 = om + h * (B1 * kom[0] + B3 * kom[2] + B4 * kom[3] + B5 * kom[4] + B6 * kom[5])
    a7 = _acc(t + h, th1, om1, pr, slide, tc)
    kth[6] = om1
    kom[6] = a7
    eth = h * (E1 * kth[0] + E3 * kth[2] + E4 * kth[3] + E5 * kth[4] + E6 * kth[5] + E7 * kth[6])
    eom = h * (E1 * kom[0] + E3 * kom[2] + E4 * kom[3] + E5 * kom[4] + E6 * kom[5] + E7 * kom[6])
    return th1, om1, a7, eth, eom


@numba.njit(cache=True)
def _dense_coefficients(h, kth, kom, S):
    """Coefficients of the 4th-order dense-output polynomials of the last step, into S."""
    for comp in range(2):
        k = kth if comp == 0 else kom
        base = S_POLY + 4 * comp
        S[base] = h * (Q11 * k[0])
        S[base + 1] = h * (
            Q12 * k[0] + Q32 * k[2] + Q42 * k[3] + Q52 * k[4] + Q62 * k[5] + Q72 * k[6]
        )
        S[base + 2] = h * (
            Q13 * k[0] + Q33 * k[2] + Q43 * k[3] + Q53 * k[4] + Q63 * k[5] + Q73 * k[6]
        )
        S[base + 3] = h * (
            Q14 * k[0] + Q34 * k[2] + Q44 * k[3] + Q54 * k[4] + Q64 * k[5] + Q74 * k[6]
        )


@numba.njit(cache=True, inline="always")
def _poly(y0, S, base, s):
    return y0 + s * (S[base] + s * (S[base + 1] + s * (S[base + 2] + s * S[base + 3])))


@numba.njit(cache=True, inline="always")
def _poly_slope(S, base, s):
    return S[base] + s * (2.0 * S[base + 1] + s * (3.0 * S[base + 2] + s * 4.0 * S[base + 3]))


@numba.njit(cache=True)
def _first_exit(y0, S, base, level, sign):
    """First s in [0, 1] where d(s) = sign (poly(s) - level) goes from >= 0 to < 0, else -1.

    The interval is cut at the polynomial's critical points (roots of its cubic
    derivative, bracketed on a fine grid), so d is monotone on each piece and an
    excursion that starts and ends inside the step (grazing) is found as well.
    """
    nodes = np.empty(6)
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
            if count < 5:
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


@numba.njit(cache=True)
def _land_theta(t, th, om, target, pr, slide, tc):
    """Henon step: integrate (t, theta') over theta from ``th`` to ``target`` exactly (RK4).

    Used after the landing step, where |target - th| is at the level of the
    integration tolerance, so one step is far more accurate than needed.
    """
    dth = target - th
    if dth == 0.0 or om == 0.0:
        return t, om
    k1t = 1.0 / om
    k1v = _acc(t, th, om, pr, slide, tc) / om
    t2 = t + 0.5 * dth * k1t
    v2 = om + 0.5 * dth * k1v
    k2t = 1.0 / v2
    k2v = _acc(t2, th + 0.5 * dth, v2, pr, slide, tc) / v2
    t3 = t + 0.5 * dth * k2t
    v3 = om + 0.5 * dth * k2v
    k3t = 1.0 / v3
    k3v = _acc(t3, th + 0.5 * dth, v3, pr, slide, tc) / v3
    t4 = t + dth * k3t
    v4 = om + dth * k3v
    k4t = 1.0 / v4
    k4v = _acc(t4, target, v4, pr, slide, tc) / v4
    t_new = t + dth * (k1t + 2.0 * k2t + 2.0 * k3t + k4t) / 6.0
    om_new = om + dth * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
    return t_new, om_new


@numba.njit(cache=True)
def _land_rest(t, th, om, pr, slide, tc):
    """Henon step with theta' as the independent variable: integrate (t, theta) to theta' = 0."""
    dom = -om
    if dom == 0.0:
        return t, th
    a = _acc(t, th, om, pr, slide, tc)
    if a == 0.0:
        return t, th
    k1t = 1.0 / a
    k1y = om / a
    v2 = om + 0.5 * dom
    t2 = t + 0.5 * dom * k1t
    y2 = th + 0.5 * dom * k1y
    a2 = _acc(t2, y2, v2, pr, slide, tc)
    k2t = 1.0 / a2
    k2y = v2 / a2
    t3 = t + 0.5 * dom * k2t
    y3 = th + 0.5 * dom * k2y
    a3 = _acc(t3, y3, v2, pr, slide, tc)
    k3t = 1.0 / a3
    k3y = v2 / a3
    t4 = t + dom * k3t
    y4 = th + dom * k3y
    a4 = _acc(t4, y4, 0.0, pr, slide, tc)
    k4t = 1.0 / a4
    k4y = 0.0
    t_new = t + dom * (k1t + 2.0 * k2t + 2.0 * k3t + k4t) / 6.0
    th_new = th + dom * (k1y + 2.0 * k2y + 2.0 * k3y + k4y) / 6.0
    return t_new, th_new


@numba.njit(cache=True)
def _push_event(events, n_events, row):
    """Append one row to the growable event buffer; returns the (possibly new) buffer."""
    if n_events >= events.shape[0]:
        bigger = np.empty((max(16, 2 * events.shape[0]), EV_SIZE))
        bigger[: events.shape[0]] = events
        events = bigger
    events[n_events, :] = row
    return events


@numba.njit(cache=True)
def _push_dense(dense, n_dense, t, th, om):
    if n_dense >= dense.shape[0]:
        bigger = np.empty((max(1024, 2 * dense.shape[0]), 3))
        bigger[: dense.shape[0]] = dense
        dense = bigger
    dense[n_dense, 0] = t
    dense[n_dense, 1] = th
    dense[n_dense, 2] = om
    return dense


@numba.njit(cache=True)
def _stick_test(t, th, pr, tc):
    """Sliding direction on leaving theta' = 0: 0 stays stuck, else the sign of the net torque."""
    a = region_acceleration(t, th, 0.0, pr)
    if abs(a) <= tc:
        return 0.0
    return 1.0 if a > 0.0 else -1.0


@numba.njit(cache=True)
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
    tc = p[P.COULOMB_ACC]
    if tc > 0.0:
        if om > 0.0:
            S[S_SLIDE] = 1.0
        elif om < 0.0:
            S[S_SLIDE] = -1.0
        else:
            S[S_SLIDE] = _stick_test(S[S_TB], th, coefficients(p, contact), tc)
            if S[S_SLIDE] == 0.0:
                S[S_STICK_T] = S[S_TB]
    else:
        S[S_SLIDE] = 1.0
    S[S_ACC_OK] = 0.0


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def restart(S, t, theta, theta_dot, p):
    """Continue from (t, theta, theta_dot): a new segment start, regions re-evaluated for ``p``."""
    S[S_TA] = t
    S[S_TB] = t
    S[S_THA] = theta
    S[S_OMA] = theta_dot
    S[S_THB] = theta
    S[S_OMB] = theta_dot
    for i in range(8):
        S[S_POLY + i] = 0.0
    initialise_regions(S, p)


@numba.njit(cache=True)
def state_at(S, t):
    """(theta, theta') at time t inside the current segment, from its dense output."""
    ta = S[S_TA]
    tb = S[S_TB]
    if tb <= ta:
        return S[S_THB], S[S_OMB]
    s = (t - ta) / (tb - ta)
    return _poly(S[S_THA], S, S_POLY, s), _poly(S[S_OMA], S, S_POLY + 4, s)


@numba.njit(cache=True)
def _initial_step(t, th, om, a, pr, slide, tc, rtol, atol):
    """Starting step size (Hairer, Norsett & Wanner, section II.4)."""
    sc0 = atol + rtol * abs(th)
    sc1 = atol + rtol * abs(om)
    d0 = math.sqrt(0.5 * ((th / sc0) ** 2 + (om / sc1) ** 2))
    d1 = math.sqrt(0.5 * ((om / sc0) ** 2 + (a / sc1) ** 2))
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    th1 = th + h0 * om
    om1 = om + h0 * a
    a1 = _acc(t + h0, th1, om1, pr, slide, tc)
    d2 = math.sqrt(0.5 * (((om1 - om) / sc0) ** 2 + ((a1 - a) / sc1) ** 2)) / h0
    h1 = max(1e-06, h0 * 0.001) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** 0.2
    return min(100.0 * h0, h1)


@numba.njit(cache=True)
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
    k_contact = coefficients(p, True)
    k_free = coefficients(p, False)
    kth = np.empty(7)
    kom = np.empty(7)
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
    last_h = 0.0  # length of the last DOPRI step whose stages sit in kth/kom (0: none)
    poly_ok = True

    while True:
        # ---- emit outputs that fall inside the current segment [TA, TB]
        ta = S[S_TA]
        tb = S[S_TB]
        need = (gi < n_out and out_t[gi] <= tb) or (pk < n_pc and pc_t0 + pk * pc_dt <= tb)
        if need:
            if not poly_ok:
                _dense_coefficients(last_h, kth, kom, S)
                poly_ok = True
            span = tb - ta
            while gi < n_out and out_t[gi] <= tb:
                s = (out_t[gi] - ta) / span if span > 0.0 else 1.0
                out_th[gi] = _poly(S[S_THA], S, S_POLY, s)
                out_om[gi] = _poly(S[S_OMA], S, S_POLY + 4, s)
                gi += 1
            while pk < n_pc and pc_t0 + pk * pc_dt <= tb:
                s = (pc_t0 + pk * pc_dt - ta) / span if span > 0.0 else 1.0
                pc_th[pk] = _poly(S[S_THA], S, S_POLY, s)
                pc_om[pk] = _poly(S[S_OMA], S, S_POLY + 4, s)
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
            for i in range(8):
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

        a1 = S[S_ACC_B] if S[S_ACC_OK] != 0.0 else _acc(t, th, om, pr, slide, tc)
        h = S[S_H]
        if h <= 0.0:
            h = _initial_step(t, th, om, a1, pr, slide, tc, rtol, atol)
        h = min(h, max_step)
        rejected = False
        while True:
            h_min = 1e-14 * max(1.0, abs(t))
            if h < h_min:
                S[S_STATUS] = STATUS_STEP_UNDERFLOW
                break
            th1, om1, a7, eth, eom = _dopri_step(t, th, om, a1, h, pr, slide, tc, kth, kom)
            steps_this_call += 1
            sth = atol + rtol * max(abs(th), abs(th1))
            som = atol + rtol * max(abs(om), abs(om1))
            err = math.sqrt(0.5 * ((eth / sth) ** 2 + (eom / som) ** 2))
            if err <= 1.0:
                break
            S[S_REJECTS] += 1
            rejected = True
            if not err < math.inf:  # NaN or inf
                h *= MIN_FACTOR
            else:
                h *= max(MIN_FACTOR, SAFETY * err**-0.2)
        if S[S_STATUS] != STATUS_OK:
            break
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-0.2))
        if rejected:
            factor = min(factor, 1.0)
        h_next = min(h * factor, max_step)
        S[S_STEPS] += 1

        # ---- events inside the accepted step
        last_h = h
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
                _dense_coefficients(h, kth, kom, S)
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
                    _dense_coefficients(h, kth, kom, S)
                    poly_ok = True
                s = _first_exit(om, S, S_POLY + 4, 0.0, slide)
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
                        _dense_coefficients(h, kth, kom, S)
                        poly_ok = True
                    S[S_THMAX] = max(S[S_THMAX], _poly_max(th, S, S_POLY))
            if abs(th1) > math.pi:
                S[S_STATUS] = STATUS_OVER_THE_TOP
            if want_dense:
                dense = _push_dense(dense, n_dense, t + h, th1, om1)
                n_dense += 1
            continue

        # ---- landing step onto the event, then exactly onto the surface
        h_land = s_event * h
        S[S_TA] = t
        S[S_THA] = th
        S[S_OMA] = om
        if h_land > 0.0:
            thl, oml, _al, _, _ = _dopri_step(t, th, om, a1, h_land, pr, slide, tc, kth, kom)
            S[S_STEPS] += 1
            steps_this_call += 1
            last_h = h_land
            poly_ok = False
            t_land = t + h_land
        else:
            thl, oml, t_land = th, om, t
            for i in range(8):
                S[S_POLY + i] = 0.0
            poly_ok = True
        if kind == 1:
            t_ev, om_ev = _land_theta(t_land, thl, oml, thb, pr, slide, tc)
            th_ev = thb
        else:
            t_ev, th_ev = _land_rest(t_land, thl, oml, pr, slide, tc)
            om_ev = 0.0
        if not (t_ev >= t):  # the Henon correction must not go back past the step start
            t_ev = t_land
        S[S_TB] = t_ev
        S[S_THB] = th_ev
        S[S_OMB] = om_ev
        S[S_ACC_OK] = 0.0
        S[S_H] = max(h_next, 1e-3 * h)
        if contact and h_land > 0.0:
            if not poly_ok:
                _dense_coefficients(last_h, kth, kom, S)
                poly_ok = True
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
            else:
                S[S_CONTACT] = 1.0
                S[S_ENTRY_T] = t_ev
                S[S_ENTRY_TH] = th_ev
                S[S_ENTRY_OM] = om_ev
                S[S_ENTRY_GRAZE] = 1.0 if grazing else 0.0
                S[S_THMAX] = th_ev
        else:
            new_slide = _stick_test(t_ev, th_ev, pr, tc)
            S[S_SLIDE] = new_slide
            if new_slide == 0.0:
                S[S_STICK_T] = t_ev

    if not poly_ok and last_h > 0.0:
        _dense_coefficients(last_h, kth, kom, S)
    return events, n_events, dense, n_dense, gi, pk


@numba.njit(cache=True)
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
