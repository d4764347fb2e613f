"""Compiled forward sensitivities: the variational equations along a run's own steps.

A plain run of the integrator with its segment record (an ``integrator.Run`` with
``dense_columns=REC_SIZE``: every segment's end, and the region it leads into) is
replayed segment by segment: each segment is one Dormand-Prince 8(5,3) step from its
start over its length, and the derivatives of the state with respect to the initial
state and to chosen entries of the packed vector are carried through it by the same step
applied to the variational equations, with each stage's Jacobian taken at that stage
(the exact derivative of the step, whose stages these are: the same arithmetic as the
run's own step, not a second integration with steps of its own). Outputs inside a
segment come from the step's dense output, differentiated the same way.

At a contact event the derivatives pass the saltation (jump) matrix of the surface
g = theta - theta_b = 0::

    Y+ = Y- + (f+ - f-) (g_y Y- + g_p) / (g_y f-)

with f the vector field (theta', theta'') on either side at the event.  The contact law
of docs/MODEL.md section 2 is continuous at the surface (its force K delta^n vanishes
there), so f+ = f- and the matrix is the identity; Kelvin-Voigt damping (``c deltadot``)
jumps at entry, and there the matrix is not.

These kernels inline the integrator's step (``integrator._rk_step``, ``rhs``) and link the
model's equations and their derivatives; numba's cache tracks only a kernel's own file, so
after editing analysis/model.py or analysis/simulate/integrator.py delete this folder's
__pycache__ (as the integrator's own note says of the model).
"""

from __future__ import annotations

import math

import numpy as np

from analysis.model import (
    K_C_VISCOUS,
    K_GAIN,
    K_MU0,
    K_SHAFT,
    acceleration_partials,
    barrier_force,
    coefficients,
    contact_law,
    indentation,
    surface_force,
)
from analysis.packed import P
from analysis.simulate.integrator import (
    A853,
    B853,
    C853,
    D853,
    DEGREE,
    M_POWER,
    N_EXTENDED,
    N_STAGES,
    _rk_step,
    kernel,
    rhs,
)

# columns of the segment record (an ``integrator.Run`` with dense_columns=REC_SIZE writes them)
REC_T = 0
REC_THETA = 1
REC_THETA_DOT = 2
REC_CONTACT = 3  # the region the motion continues in: 1.0 contact
REC_SLIDE = 4  # and its sliding direction (+1, -1; 0 stuck)
REC_SIZE = 5
PACKED_SIZE = int(P.SIZE)
# Inside a contact the stage Jacobians hold delta^(n - 1) (sqrt(delta) for Hertz), which
# vanishes at the surface without being smooth there: a step that starts or ends on the
# surface integrates the sensitivities with an error of order h^(3/2), far above the
# run's own (its force, delta^(3/2), is smooth enough).  Such a step is replayed as pieces
# halving toward the surface, GRADED_LEVELS of them, which takes that error below the
# run's tolerance.
GRADED_LEVELS = 8


@kernel(inline="always")
def _stage_rates(t, th, om, k, slide, tc, columns, d_p, cos_b, yt, yo, out, unclamped):
    """theta'' at one stage, and into ``out`` the rate of each column's theta' there: the
    state derivatives (yt, yo) through the stage's Jacobian, plus each parameter's own
    term.  ``unclamped``: the contact law continued past its clamp (``_clamp_fraction``)."""
    d_th, d_om, _ = acceleration_partials(t, th, om, k, slide, tc, d_p, not unclamped)
    m = yt.shape[0]
    for j in range(m):
        out[j] = d_th * yt[j] + d_om * yo[j]
    for j in range(2, m):
        index = columns[j - 2]
        if index == P.THETA_B:  # the equation reads theta_b as sin(theta_b)
            out[j] += d_p[P.SIN_THETA_B] * cos_b
        else:
            out[j] += d_p[index]
    acc = rhs(t, th, om, k, slide, tc)
    if unclamped:  # the law's own value where the force would be clamped at 0
        s = math.sin(th)
        c = math.cos(th)
        acc += k[K_GAIN] * (barrier_force(s, c, om, k) - contact_law(s, c, om, k))
    return acc


@kernel
def _variational_step(t, th, om, h, k, slide, tc, columns, d_p, cos_b, y_th, y_om, kt, ko,
                      st, so, yt_end, yo_end, unclamped, dense):
    """One DOP853 step of length h from (t, theta, theta') carrying the sensitivities
    (y_th, y_om): the stages of the step (and with ``dense`` those of its dense output) into
    kt/ko (theta', theta'') and st/so (their derivatives, one column each), the
    sensitivities at the step's end into yt_end/yo_end; returns theta, theta' there."""
    m = y_th.shape[0]
    th1 = th
    om1 = om
    for s in range(N_EXTENDED if dense else N_STAGES + 1):
        end = s == N_STAGES  # stage 12 is f at the step's end, on the 8th-order solution
        t_s = t + h if end else t + C853[s] * h
        th_s = th
        om_s = om
        for j in range(m):
            yt_end[j] = y_th[j]
            yo_end[j] = y_om[j]
        for i in range(N_STAGES if end else s):
            a = h * (B853[i] if end else A853[s, i])
            if a != 0.0:
                th_s += a * kt[i]
                om_s += a * ko[i]
                for j in range(m):
                    yt_end[j] += a * st[i, j]
                    yo_end[j] += a * so[i, j]
        if end:
            th1 = th_s
            om1 = om_s
        kt[s] = om_s
        for j in range(m):
            st[s, j] = yo_end[j]
        ko[s] = _stage_rates(t_s, th_s, om_s, k, slide, tc, columns, d_p, cos_b, yt_end,
                             yo_end, so[s], unclamped)
    if not dense:  # stage 12 left the end's sensitivities in yt_end / yo_end
        return th1, om1
    # the stages after 12 overwrote the end's sensitivities: take them again
    for j in range(m):
        acc_t = y_th[j]
        acc_o = y_om[j]
        for i in range(N_STAGES):
            b = h * B853[i]
            acc_t += b * st[i, j]
            acc_o += b * so[i, j]
        yt_end[j] = acc_t
        yo_end[j] = acc_o
    return th1, om1


@kernel
def _dense_sensitivity(h, y0, y1, stages, coef):
    """Coefficients of the dense output's derivative (the nominal run's interpolant applied
    to the stages' derivatives ``stages``, one column each), into coef[DEGREE, m]: the
    sensitivity at fraction s of the step is y0 + sum_j coef[j] s^(j+1)."""
    m = y0.shape[0]
    f = np.empty(DEGREE)
    for j in range(m):
        delta = y1[j] - y0[j]
        f[0] = delta
        f[1] = h * stages[0, j] - delta
        f[2] = 2.0 * delta - h * (stages[N_STAGES, j] + stages[0, j])
        for r in range(4):
            acc = 0.0
            for i in range(N_EXTENDED):
                acc += D853[r, i] * stages[i, j]
            f[3 + r] = h * acc
        for q in range(DEGREE):
            acc = 0.0
            for i in range(DEGREE):
                acc += M_POWER[q, i] * f[i]
            coef[q, j] = acc


@kernel(inline="always")
def _dense_value(y0, coef, s, out):
    for j in range(y0.shape[0]):
        acc = coef[DEGREE - 1, j]
        for q in range(DEGREE - 2, -1, -1):
            acc = coef[q, j] + s * acc
        out[j] = y0[j] + s * acc


@kernel
def _law_at(t, th, om, s, h, k, slide, tc):
    """The unclamped contact law at fraction s of the step of length h from (t, th, om)."""
    if s == 0.0:
        return contact_law(math.sin(th), math.cos(th), om, k)
    th1, om1, _, _, _ = _rk_step(t, th, om, rhs(t, th, om, k, slide, tc), s * h, k, slide, tc,
                                 1.0, 1.0, 0.0)
    return contact_law(math.sin(th1), math.cos(th1), om1, k)


@kernel
def _clamps(th, om, th_end, om_end, k):
    """Whether the contact law turns adhesive (the force clamped at 0) inside a contact step
    from (th, om) to (th_end, om_end): positive at its start, not at its end, or, for a
    step ending on the surface, not just inside it (where K delta^n vanishes: the sign of
    c deltadot, else of 1 + mu0 deltadot)."""
    if not contact_law(math.sin(th), math.cos(th), om, k) > 0.0:
        return False
    if indentation(math.sin(th_end), k) > 0.0:
        return not contact_law(math.sin(th_end), math.cos(th_end), om_end, k) > 0.0
    delta_dot = k[K_SHAFT] * math.cos(th_end) * om_end
    if k[K_C_VISCOUS] != 0.0 and delta_dot != 0.0:
        return k[K_C_VISCOUS] * delta_dot < 0.0
    return not 1.0 + k[K_MU0] * delta_dot > 0.0


@kernel
def _clamp_fraction(t, th, om, h, k, slide, tc):
    """Where in the contact step of length h from (t, th, om), which ``_clamps``, the force
    is clamped: the fraction of the step, found by the Illinois method (regula falsi whose
    retained end's value is halved when it is kept twice); -1 when only at its end."""
    lo = 0.0
    hi = 1.0
    f_lo = _law_at(t, th, om, lo, h, k, slide, tc)
    f_hi = _law_at(t, th, om, hi, h, k, slide, tc)
    if f_hi == 0.0:  # the step ends on the surface: the law's end value is not its limit
        f_hi = -f_lo
    side = 0
    for _ in range(100):
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
        f_mid = _law_at(t, th, om, mid, h, k, slide, tc)
        if f_mid > 0.0:
            lo = mid
            f_lo = f_mid
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi = mid
            f_hi = f_mid if f_mid != 0.0 else -f_lo
            if side == -1:
                f_lo *= 0.5
            side = -1
        if hi - lo < 1e-14:
            break
    return 0.5 * (lo + hi) if hi < 1.0 - 1e-9 else -1.0


@kernel
def _pieces(graded_start, graded_end, cuts):
    """Cut a segment into pieces: fractions cuts[0] = 0 < ... < cuts[count] = 1 (count is
    returned), halving toward its start and / or its end as asked (one piece if neither)."""
    count = 0
    cuts[0] = 0.0
    if graded_start and graded_end:
        for level in range(GRADED_LEVELS, 0, -1):
            count += 1
            cuts[count] = 0.5 * 0.5**level
        count += 1
        cuts[count] = 0.5
        for level in range(1, GRADED_LEVELS + 1):
            count += 1
            cuts[count] = 1.0 - 0.5 * 0.5**level
    elif graded_start:
        for level in range(GRADED_LEVELS, 0, -1):
            count += 1
            cuts[count] = 0.5**level
    elif graded_end:
        for level in range(1, GRADED_LEVELS + 1):
            count += 1
            cuts[count] = 1.0 - 0.5**level
    count += 1
    cuts[count] = 1.0
    return count


@kernel
def _insert_cut(cuts, count, s):
    """Add fraction s to the cuts cuts[0..count] (increasing); returns the new count."""
    i = count
    while i > 0 and cuts[i - 1] > s:
        i -= 1
    if cuts[i - 1] == s or cuts[i] == s:
        return count
    for j in range(count, i - 1, -1):
        cuts[j + 1] = cuts[j]
    cuts[i] = s
    return count + 1


@kernel(nogil=True)
def propagate(p, columns, t0, theta0, theta_dot0, contact0, slide0, record, n_record, out_t,
              n_out, sens):
    """Sensitivities of theta, theta' at out_t[:n_out] (the outputs the run wrote) into
    sens[:n_out, 0 or 1, column], from the run's segment record ``record[:n_record]``
    (layout ``REC_*``) that started at (t0, theta0, theta_dot0) in region (contact0,
    slide0).  Column 0 is theta0, 1 theta_dot0, 2 + i the packed entry columns[i]."""
    tc = p[P.COULOMB_ACC]
    thb = p[P.THETA_B]
    cos_b = math.cos(thb)
    k_contact = coefficients(p, True)
    k_free = coefficients(p, False)
    m = 2 + columns.shape[0]
    y_th = np.zeros(m)
    y_om = np.zeros(m)
    y_th[0] = 1.0
    y_om[1] = 1.0
    yt_end = np.empty(m)
    yo_end = np.empty(m)
    kt = np.empty(N_EXTENDED)
    ko = np.empty(N_EXTENDED)
    st = np.empty((N_EXTENDED, m))
    so = np.empty((N_EXTENDED, m))
    ct = np.empty((DEGREE, m))
    co = np.empty((DEGREE, m))
    d_p = np.empty(PACKED_SIZE)
    g_p = np.zeros(m)  # the surface theta - theta_b's own derivative: -1 for theta_b
    for j in range(2, m):
        if columns[j - 2] == P.THETA_B:
            g_p[j] = -1.0
    ta = t0
    th = theta0
    om = theta_dot0
    contact = contact0
    slide = slide0
    cuts = np.empty(2 * GRADED_LEVELS + 4)
    was_contact = contact0
    gi = 0
    while gi < n_out and out_t[gi] <= ta:
        sens[gi, 0, :] = y_th
        sens[gi, 1, :] = y_om
        gi += 1
    for r in range(n_record):
        tb = record[r, REC_T]
        h = tb - ta
        k = k_contact if contact else k_free
        if slide != 0.0 and h > 0.0:
            # at the contact's two ends the Jacobian goes as sqrt(delta): grade the pieces
            pieces = _pieces(contact and not was_contact,
                             contact and record[r, REC_CONTACT] == 0.0, cuts)
            # the clamp is a kink of the field, where its Jacobian jumps: a piece ends there,
            # the pieces before it see the law continued smoothly (their last stages sit on
            # the kink), those after it no force at all (free flight's field)
            clamp = -1.0
            if contact and _clamps(th, om, record[r, REC_THETA], record[r, REC_THETA_DOT], k):
                clamp = _clamp_fraction(ta, th, om, h, k, slide, tc)
            if clamp > 0.0:
                pieces = _insert_cut(cuts, pieces, clamp)
            thp = th
            omp = om
            for q in range(pieces):
                tp = ta + cuts[q] * h
                tq = tb if q == pieces - 1 else ta + cuts[q + 1] * h
                hp = tq - tp
                before = clamp > 0.0 and cuts[q] < clamp
                kp = k_free if clamp > 0.0 and not before else k
                sampled = gi < n_out and out_t[gi] <= tq
                thp, omp = _variational_step(tp, thp, omp, hp, kp, slide, tc, columns, d_p,
                                             cos_b, y_th, y_om, kt, ko, st, so, yt_end, yo_end,
                                             before, sampled)
                if sampled:
                    _dense_sensitivity(hp, y_th, yt_end, st, ct)
                    _dense_sensitivity(hp, y_om, yo_end, so, co)
                    while gi < n_out and out_t[gi] <= tq:
                        s = (out_t[gi] - tp) / hp
                        _dense_value(y_th, ct, s, sens[gi, 0])
                        _dense_value(y_om, co, s, sens[gi, 1])
                        gi += 1
                y_th[:] = yt_end
                y_om[:] = yo_end
        else:  # stuck (theta' stays 0) or a segment of no length
            while gi < n_out and out_t[gi] <= tb:
                sens[gi, 0, :] = y_th
                sens[gi, 1, :] = y_om
                gi += 1
        th = record[r, REC_THETA]
        om = record[r, REC_THETA_DOT]
        new_contact = record[r, REC_CONTACT] != 0.0
        if new_contact != contact and om != 0.0:
            # saltation at the surface: only theta'' can jump, by the contact force's limit
            jump = k_contact[K_GAIN] * surface_force(math.cos(th), om, k_contact)
            if new_contact:
                jump = -jump
            for j in range(m):
                y_om[j] += jump * (y_th[j] + g_p[j]) / om
        ta = tb
        was_contact = contact
        contact = new_contact
        slide = record[r, REC_SLIDE]
