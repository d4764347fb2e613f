"""A term to propose when no named cause explains a record: a sparse regression of the
residual acceleration on a library of candidate terms, in free flight and in contact
separately (on a decay, the flight regression is in weak form: :func:`.weak_flight`).

The residual acceleration is the model's equation error at the data's states: the
measured angle's Savitzky-Golay second derivative minus the model's acceleration
(docs/MODEL.md section 2, with the model's named causes) at the smoothed angle and rate.
Both sides pass the same smoother: its second derivative is ``g * D2`` (``D2`` the second
difference), so the model's acceleration and every library column are filtered by ``g``.
The model's contact condition (penetration > 0) splits the samples: flight where no
contact lies within reach of the smoothers, contact the rest.  A contact (about 10 ms)
is shorter than the smoother, whose angle cuts its peak: there the fitted model's own
states stand in for the data's (with smoothed states a clean record's contact residual
was 80 % a delta^1.5 term).  In flight, residual and columns are low-passed alike once
more, at the highest library harmonic and one (a linear filter on both sides of a
linear regression changes no coefficient, and the second derivative's noise grows as
the frequency to the fourth), then decimated.

Libraries, each column scaled to unit rms before the regression:
  flight: a constant (see :func:`flight_library`), theta, theta', sign(theta'),
  ``theta'|theta'|``, theta^3, and sin, cos of the drive harmonics 1..3 of the model's drive;
  contact: delta^n and delta^n delta' for n = 0.5, 1, 1.5, 2 (delta the penetration).

Selection: sequentially thresholded least squares (pysindy's STLSQ, a published, tested
implementation; nothing here needs a variant of it) over a path of thresholds gives the
candidate term sets.  They are scored on held-out data: the record is cut into
HELDOUT_BLOCKS contiguous blocks in time, each set is fitted on the even blocks and
judged on the odd ones and the other way round, and the set with the least held-out
residual variance wins.  Then every term in it must earn its place: dropping it must
raise each block's held-out squares significantly (a paired t-test over the blocks of
the log of their ratio, at FALSE_ALARM, one-sided, divided among the library's terms)
and by at least MIN_GAIN of the region's held-out squares;
the failing term of least t is dropped until all pass.  Coefficients are the least
squares over every block, with 95 % intervals from a delete-one-block jackknife.

Why not the held-out forecast judge of the named causes
(:mod:`analysis.discrepancy.forced_judges`): it simulates each model with the compiled
integrator, whose equation has a fixed set of terms (the packed vector of
:mod:`analysis.packed`); an arbitrary library term cannot enter it without changing the
compiled equations.  The judge here is held-out equation error instead: the same
held-out principle, on the residual acceleration rather than on forecasts.  A kept term
is reported as a proposed term, never as a named cause.  A model that compromised on its
own parameters for a missing term leaves corrections of its own terms (theta, theta',
the constant, the drive's first harmonic; in contact the Hunt-Crossley law's): those are
fitted beside every candidate set and never proposed (FLIGHT_OWN, CONTACT_OWN).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.polynomial import Legendre, Polynomial
from scipy import stats
from scipy.signal import savgol_coeffs, savgol_filter

from analysis.dynamics.lines import FALSE_ALARM
from analysis.model import acceleration
from analysis.packed import P

SMOOTHING_S = 0.012  # the flight regression's smoother: resolves drive harmonics past 10 Hz
POLYORDER = 3
DRIVE_HARMONICS = 3
CONTACT_EXPONENTS = (0.5, 1.0, 1.5, 2.0)
# The model's own terms, whose coefficients its fitted parameters set (docs/MODEL.md
# section 2): in flight the sensor zero (a constant), the pendulum's frequency (theta),
# its damping (theta') and the table's amplitude and phase (the first drive harmonic);
# in contact K and mu0 of the Hunt-Crossley law.  A baseline that compromised on them for
# a missing term leaves corrections of them in its residual: these are fitted beside the
# candidates, never proposed.
# Over a contact the penetration's powers and their damping forms correlate by 0.98-0.99
# with each other and with the model's own law: two or more of them fit the shape of a
# trajectory's misfit, not a law (a hairspring record's baseline drew delta^1, delta^2 and
# delta^2 delta' at once), so a contact asks for one term at most.
CONTACT_MOST = 1
FLIGHT_OWN = ("1", "theta", "theta'", "sin(1 Omega t)", "cos(1 Omega t)")
CONTACT_OWN = ("delta^1.5", "delta^1.5 delta'")
HELDOUT_BLOCKS = 20  # contiguous blocks in time, alternately fitted and held out
# STLSQ thresholds on the scaled columns (coefficients as fractions of the residual's rms
# per rms of the column), largest first: each gives a candidate term set
THRESHOLDS = tuple(float(x) for x in np.geomspace(0.5, 0.002, 14))
RIDGE = 1e-6  # STLSQ's ridge on the scaled columns: only keeps the normal equations regular
# A kept term must remove at least this share of its region's held-out residual variance:
# a significance test alone, over tens of thousands of samples, keeps terms too small to
# matter (a smoother's bias at a sharp turn, say)
MIN_GAIN = 0.02
# A term that could stand in place of a proposed one unless the proposed one fits the
# held-out blocks better at this one-sided level (a rival is listed, not proposed)
RIVAL_LEVEL = 0.05
MIN_SAMPLES = 200  # a region with fewer usable samples is not regressed
# With the barrier in, test functions per flight (see weak_windows): independent rows a
# held-out block adds, each flight's one window being too short to slide
FLIGHT_TEST_FUNCTIONS = 3
MIN_HALF = 8  # a flight shorter than 2 MIN_HALF + 1 samples holds no window
# the weak form's rows per library term at least: each fold fits every term on half of them
WEAK_ROWS_PER_TERM = 4
SWING_SHARE = 0.3  # a decay is regressed while its swing is above this share of its largest
DECIMATION = 16  # low-passed flight samples kept: this many per low-pass window


def rules_json() -> dict[str, dict[str, Any]]:
    """The proposal's fixed rules, each as ``{"value", "why"}`` (a report's ``policy``)."""
    return {
        "min_gain": {"value": MIN_GAIN, "why": "a proposed term removes at least this share "
                     "of its region's held-out residual variance"},
        "false_alarm": {"value": FALSE_ALARM, "why": "a kept term's paired test over the "
                        "held-out blocks, divided among the terms tried"},
        "rival_level": {"value": RIVAL_LEVEL, "why": "a term is listed as an alternative "
                        "unless the proposed one fits the held-out blocks better at this "
                        "one-sided level"},
    }


@dataclass(frozen=True)
class Library:
    """Candidate terms of one region: names, the unit of each term, and its columns (one per
    term, over the region's samples)."""

    region: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    columns: np.ndarray  # (samples, terms)
    # the model's own terms (what its fitted parameters already scale): always in the
    # regression, so that a compromise of those parameters is corrected there, and never
    # proposed
    own: tuple[int, ...] = ()
    most: int | None = None  # at most this many terms proposed (None: any number)


@dataclass(frozen=True)
class ProposedTerm:
    """A term the record asks for: theta'' gains ``coefficient`` times ``term`` (its 95 %
    interval from a jackknife over the held-out blocks), in ``region``, removing
    ``heldout_gain`` of that region's held-out residual variance (``t`` its paired
    t-statistic over the blocks)."""

    term: str
    region: str
    coefficient: float
    ci95: tuple[float, float]
    unit: str
    heldout_gain: float
    t: float
    # terms the record cannot tell from this one: each in its place fits the held-out
    # blocks about as well
    alternatives: tuple[str, ...] = ()

    def sentence(self) -> str:
        """One line for the text report."""
        low, high = self.ci95
        rivals = (f"; or {' or '.join(self.alternatives)} in its place, which the record "
                  "cannot tell from it" if self.alternatives else "")
        return (f"proposed term (not a named cause): theta'' += {self.coefficient:.4g} "
                f"[{low:.4g}, {high:.4g}] {self.unit} x {self.term} in {self.region}, "
                f"removing {100 * self.heldout_gain:.3g} % of its held-out residual "
                f"acceleration variance (t = {self.t:.3g}){rivals}")

    def as_json(self) -> dict[str, Any]:
        """An entry of the report's ``proposed_terms``."""
        return {"term": self.term, "region": self.region, "coefficient": self.coefficient,
                "ci95": list(self.ci95), "unit": self.unit, "heldout_gain": self.heldout_gain,
                "t": self.t, "alternatives": list(self.alternatives), "text": self.sentence()}


@dataclass(frozen=True)
class EquationError:
    """The residual acceleration, the states it was taken at, which samples can be used,
    and which are in flight (no contact within reach of the smoothers) or in contact."""

    residual: np.ndarray  # [rad/s^2]
    theta: np.ndarray
    rate: np.ndarray
    flight: np.ndarray
    contact: np.ndarray
    window: int  # the smoother's, in samples
    lowpass: int  # the flight regression's extra low-pass, in samples
    angle: np.ndarray  # the data's angle, gaps filled (what the weak form integrates)
    free: np.ndarray  # usable and clear of contacts by the smoother's reach (weak form)
    model_acceleration: np.ndarray  # the model's at (theta, rate), unfiltered [rad/s^2]


def propose_terms(t: np.ndarray, theta: np.ndarray, valid: np.ndarray, packed: np.ndarray,
                  model_theta: np.ndarray, model_rate: np.ndarray) -> list[ProposedTerm]:
    """Terms that the residual acceleration of the model ``packed`` (the compiled equations'
    parameter vector) asks for, flight first; [] when none earns its place.  ``theta`` is
    the data's true angle (the measured one with the model's sensor taken off), NaN or
    not ``valid`` where unusable; ``model_theta`` and ``model_rate`` the fitted model's
    states, which stand in for the data's inside contacts (see the module's docstring)."""
    error = equation_error(t, theta, valid, packed, model_theta, model_rate)
    span = np.ones(t.size, dtype=bool) if driven(packed) else large_swings(error.theta)
    blocks = time_blocks(t, t[np.flatnonzero(span)[-1]])
    error = replace(error, flight=error.flight & span, contact=error.contact & span,
                    free=error.free & span)
    flight = flight_library(t, error.theta, error.rate, packed)
    if not driven(packed):
        proposed = select_terms(*weak_flight(t, error, flight, base_frequency_hz(packed),
                                             bool(packed[P.BARRIER] != 0.0)),
                                least=WEAK_ROWS_PER_TERM * len(flight.names))
        return proposed + _contact_terms(error, packed, blocks)
    columns = smoothed_like_acceleration(flight.columns, error.window)
    columns = savgol_filter(columns, error.lowpass, POLYORDER, axis=0)
    residual = savgol_filter(error.residual, error.lowpass, POLYORDER)
    # the low-passed flight samples are oversampled: DECIMATION per low-pass window carry
    # what they hold (coarser, the low-pass's sidelobes alias noise back)
    use = error.flight & (np.arange(t.size) % max(1, error.lowpass // DECIMATION) == 0)
    proposed = select_terms(replace(flight, columns=columns[use]), residual[use], blocks[use])
    return proposed + _contact_terms(error, packed, blocks)


def _contact_terms(error: EquationError, packed: np.ndarray,
                   blocks: np.ndarray) -> list[ProposedTerm]:
    """The contact library's terms the residual acceleration in contact asks for."""
    contact = contact_library(error.theta, error.rate, packed)
    columns = smoothed_like_acceleration(contact.columns, error.window)
    use = error.contact
    return select_terms(replace(contact, columns=columns[use]), error.residual[use],
                        blocks[use])


def time_blocks(t: np.ndarray, end: float) -> np.ndarray:
    """Each time's held-out block: HELDOUT_BLOCKS equal spans from ``t[0]`` to ``end`` (times
    after it in the last); none for no times (a decay whose flights no window fits)."""
    if t.size == 0:
        return np.zeros(0, dtype=int)
    spans = HELDOUT_BLOCKS * (t - t[0]) / max(end - t[0], 1e-300)
    return np.minimum(spans.astype(int), HELDOUT_BLOCKS - 1)


def weak_flight(t: np.ndarray, error: EquationError, flight: Library, base_hz: float,
                barrier: bool) -> tuple[Library, np.ndarray, np.ndarray]:
    """The flight regression in weak form (a decay's): the equation theta'' = f + sum of
    terms, integrated against smooth test functions wholly in flight, with theta'' moved
    onto their second derivative by integrating by parts twice.  The data's second
    derivative, whose noise grows as the frequency squared, never enters: its noise is the
    angle's, averaged by the test function's second derivative (the weak SINDy of D. A.
    Messenger and D. M. Bortz, "Weak SINDy", Multiscale Model. Simul. 19 (2021)).  A
    hairspring's theta^3 (truth -279 rad/s^2 per rad^3), which the strong form fitted but
    could not tell from its noise (1.9 % of the held-out squares, 3.5 standard errors),
    comes out at -279 [-282, -275] (seed 7000 of ``reference/decays.py``), 98.6 % of them,
    t 23.9 over the held-out blocks.

    The windows are :func:`weak_windows`'s.  Each window's rows (its test functions) are
    whitened by their noise covariance, the angle's white noise through the test
    functions' second derivatives (the covariance-weighted weak form of D. M. Bortz, D. A.
    Messenger and V. Dukic, "Direct estimation of parameters in ODE models using WENDy",
    Bull. Math. Biol. 85 (2023)): rows of independent noise of one size, so that the
    held-out blocks' squares add rows of like weight.  Returns the library over the rows,
    the weak residual and each row's block, for :func:`select_terms`: the blocks divide the
    windows' own centres, from the first to the last (the samples' blocks would leave the
    last block a few windows, as a window a swing long does not fit near the span's end,
    and one such block's share of its few squares, at -2.6, hid a cubic damping that took
    69 % of the held-out squares: t 2.5 over the blocks)."""
    dt = float(t[1] - t[0])
    centres, halves, orders = weak_windows(error.free, max(8, round(0.5 / (base_hz * dt))),
                                           barrier)
    residual = np.zeros((centres.size, orders))
    columns = np.zeros((centres.size, orders, flight.columns.shape[1]))
    for half in np.unique(halves):
        phi, phi2 = test_functions(half, orders)
        phi2 = phi2 / (half * dt) ** 2
        # rows of unit, independent noise: L^-1 times them, L L' their covariance per unit
        # noise variance of the angle
        whiten = np.linalg.inv(np.linalg.cholesky(dt * dt * phi2.T @ phi2))
        these = np.flatnonzero(halves == half)
        windows = centres[these, None] + np.arange(-half, half + 1)[None, :]
        rows = dt * (error.angle[windows] @ phi2 - error.model_acceleration[windows] @ phi)
        residual[these] = rows @ whiten.T
        weak = dt * np.einsum("wik,ij->wjk", flight.columns[windows], phi)
        columns[these] = np.einsum("lj,wjk->wlk", whiten, weak)
    ends = t[centres[-1]] if centres.size else t[0]
    blocks = np.repeat(time_blocks(t[centres], ends), orders)
    return (replace(flight, columns=columns.reshape(-1, flight.columns.shape[1])),
            residual.ravel(), blocks)


def weak_windows(free: np.ndarray, swing: int, barrier: bool) -> tuple[np.ndarray, np.ndarray,
                                                                        int]:
    """The weak form's windows wholly in the ``free`` samples: their centres, half-lengths
    (samples) and test functions per window.

    A free decay is one long flight: windows one ``swing`` long (samples), a sixteenth
    apart, one test function each.  With the barrier in, a flight lasts about half a swing
    and holds one window, as long as the flight (the weak residual's signal grows as the
    window's half-length h, its noise falls as h^-1.5), probed by FLIGHT_TEST_FUNCTIONS
    test functions.  Fixed windows of a quarter swing, a sixteenth apart, left a softening
    hairspring's theta^3 (seed 7053) 40 % of the held-out squares at t 3.3; one window
    per flight 91 % at t 4.1, whose blocks held one window each: the log of a ratio of
    two single squares (variance about 10) put four of twenty blocks below zero; three
    test functions per flight, 86 % at t 5.8.
    """
    if not barrier:
        centres = np.arange(swing, free.size - swing, max(1, swing // 8))
        inside = np.array([bool(free[c - swing:c + swing + 1].all()) for c in centres],
                          dtype=bool)
        return centres[inside], np.full(int(np.count_nonzero(inside)), swing), 1
    edges = np.diff(np.concatenate([[0], free.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # [start, stop)
    halves = np.minimum((stops - starts - 1) // 2, swing)
    keep = halves >= MIN_HALF
    return (starts + halves)[keep], halves[keep], FLIGHT_TEST_FUNCTIONS


def test_functions(half: int, orders: int) -> tuple[np.ndarray, np.ndarray]:
    """The test functions (1 - s^2)^4 P_k(s), k < ``orders`` (P_k Legendre's polynomials, s
    from -1 to 1 over 2 ``half`` + 1 samples), and their second derivatives in s, as
    columns: the even ones see the flight's symmetric part (a restoring term), the odd ones
    its lopsided part (a damping); they and their first derivatives vanish at the ends."""
    s = np.arange(-half, half + 1) / half
    bump = Polynomial([1.0, 0.0, -1.0]) ** 4
    polys = [bump * Legendre.basis(k).convert(kind=Polynomial) for k in range(orders)]
    return (np.column_stack([p(s) for p in polys]),
            np.column_stack([p.deriv(2)(s) for p in polys]))


def equation_error(t: np.ndarray, theta: np.ndarray, valid: np.ndarray, packed: np.ndarray,
                   model_theta: np.ndarray, model_rate: np.ndarray) -> EquationError:
    """The data's acceleration (Savitzky-Golay) minus the model's at the data's states (the
    smoothed angle and rate in flight, the fitted model's in and near contacts), the latter
    filtered as the data's is (see the module's docstring)."""
    dt = float(t[1] - t[0])
    window = max(POLYORDER + 2, round(SMOOTHING_S / dt) | 1)
    lowpass = lowpass_window(base_frequency_hz(packed), 1.0 / dt)
    good = valid & np.isfinite(theta) & np.isfinite(model_theta) & np.isfinite(model_rate)
    idx = np.arange(theta.size)
    filled = np.interp(idx, idx[good], theta[good])
    smooth = savgol_filter(filled, window, POLYORDER)
    rate = savgol_filter(filled, window, POLYORDER, deriv=1, delta=dt)
    data_acc = savgol_filter(filled, window, POLYORDER, deriv=2, delta=dt)
    half = window // 2
    touching = in_contact(smooth, packed) | in_contact(np.where(good, model_theta, 0.0), packed)
    modelled = _widened(touching, 2 * half)  # every state the contact samples' filter reads
    theta_at = np.where(modelled & good, model_theta, smooth)
    rate_at = np.where(modelled & good, model_rate, rate)
    model_acc = np.array([acceleration(ti, a, b, packed)
                          for ti, a, b in zip(t, theta_at, rate_at, strict=True)])
    residual = data_acc - smoothed_like_acceleration(model_acc, window)
    usable = ~_widened(~good, half)
    usable[:half] = usable[-half:] = False
    reach = half + lowpass // 2
    flight = ~_widened(~usable | touching, reach)
    contact = usable & _widened(touching, half)
    free = usable & ~_widened(touching, half)
    return EquationError(residual, theta_at, rate_at, flight, contact, window, lowpass,
                         filled, free, model_acc)


def large_swings(theta: np.ndarray) -> np.ndarray:
    """A decay's samples up to where its swing (the largest angle still to come) falls
    below SWING_SHARE of the largest: an unregistered term grows with the swing (a
    hairspring's theta^3 as its cube), and the small swings after that are noise to the
    regression, and would dilute every held-out block's gain (a hairspring's theta^3,
    fitted within 1 % of the truth over the whole decay, gained 0.9 % of the held-out
    squares at 1.9 standard errors over blocks of the whole decay, 1.9 % at 3.5 over blocks
    of its large swings)."""
    ahead = np.maximum.accumulate(np.abs(theta - np.median(theta))[::-1])[::-1]
    return ahead >= SWING_SHARE * ahead[0]


def driven(packed: np.ndarray) -> bool:
    """Whether the model's table moves (a forced record; a decay's does not)."""
    return bool(packed[P.OMEGA_DRIVE] > 0.0)


def base_frequency_hz(packed: np.ndarray) -> float:
    """The frequency whose harmonics the flight library and its low-pass reach: the drive's
    on a forced record, the pendulum's own small-swing frequency on a decay."""
    omega = packed[P.OMEGA_DRIVE] if driven(packed) else math.sqrt(packed[P.OMEGA2])
    return float(omega / (2.0 * math.pi))


def lowpass_window(drive_hz: float, sample_rate_hz: float) -> int:
    """Samples of the cubic Savitzky-Golay smoother whose -3 dB frequency is the highest
    harmonic of the flight library's (of ``drive_hz``, the base frequency) and one more:
    it takes out the smoothed second
    derivative's noise, which grows as the frequency to the fourth, and no term's signal
    (R. W. Schafer, "What is a Savitzky-Golay filter?", IEEE Signal Processing Magazine
    28 (2011): f_c = (N + 1) / (3.2 M - 4.6) fs / 2 for order N and M samples)."""
    cutoff = (DRIVE_HARMONICS + 1) * drive_hz
    samples = ((POLYORDER + 1) * sample_rate_hz / (2.0 * cutoff) + 4.6) / 3.2
    return max(POLYORDER + 2, round(samples) | 1)


def smoothed_like_acceleration(values: np.ndarray, window: int) -> np.ndarray:
    """``values`` (accelerations, or columns of them) filtered by the kernel g with
    Savitzky-Golay's second derivative = g * (second difference / dt^2): what that
    smoother makes of an acceleration."""
    second = savgol_coeffs(window, POLYORDER, deriv=2, delta=1.0, use="conv")
    # exact: the kernel annihilates constants and lines, so the second difference divides it
    g, _ = np.polydiv(second, np.array([1.0, -2.0, 1.0]))
    if values.ndim == 1:
        return np.convolve(values, g, mode="same")
    return np.column_stack([np.convolve(c, g, mode="same") for c in values.T])


def in_contact(theta: np.ndarray, packed: np.ndarray) -> np.ndarray:
    """The model's contact condition (docs/MODEL.md section 2): penetration > 0 below the
    horizontal, with the barrier in place."""
    return (penetration(theta, packed) > 0.0) & (np.cos(theta) > 0.0) & \
        (packed[P.BARRIER] != 0.0)


def penetration(theta: np.ndarray, packed: np.ndarray) -> np.ndarray:
    """delta = l (sin theta - sin theta_b) [m]."""
    return packed[P.SHAFT_L] * (np.sin(theta) - packed[P.SIN_THETA_B])


def flight_library(t: np.ndarray, theta: np.ndarray, rate: np.ndarray,
                   packed: np.ndarray) -> Library:
    """The flight terms: a constant, theta, theta', sign(theta'), ``theta'|theta'|``, theta^3;
    when the table moves, the drive harmonics' sines and cosines (phase of the model's
    drive); when it does not (a decay), the products theta'^3 and theta^2 theta' (a damping
    that grows with the rate or the angle).  Over swings of one size theta'^3 and
    ``theta'|theta'|`` correlate by 0.98 and a record cannot tell them apart (a hidden drag was
    proposed as theta'^3); a decay's swing shrinks, and they scale apart (A^3 against A^2).

    The constant is not in issue 15's list: a model that compromised on its sensor zero
    measures theta from a shifted zero, and a term about a shifted zero has a constant
    part that would otherwise leak into the odd terms (a hairspring record, fitted zero
    0.019 rad off: theta^3 -49 without it, -445 with it, truth -403 rad/s^2 per rad^3)."""
    phase = packed[P.OMEGA_DRIVE] * t + packed[P.PHASE0]
    names = ["1", "theta", "theta'", "sign(theta')", "theta'|theta'|", "theta^3"]
    units = ["1", "rad", "rad/s", "1", "rad^2/s^2", "rad^3"]
    columns = [np.ones_like(theta), theta, rate, np.sign(rate), rate * np.abs(rate),
               theta * theta * theta]
    if driven(packed):
        for k in range(1, DRIVE_HARMONICS + 1):
            names += [f"sin({k} Omega t)", f"cos({k} Omega t)"]
            units += ["1", "1"]
            columns += [np.sin(k * phase), np.cos(k * phase)]
    else:
        names += ["theta'^3", "theta^2 theta'"]
        units += ["rad^3/s^3", "rad^3/s"]
        columns += [rate * rate * rate, theta * theta * rate]
    own = tuple(names.index(name) for name in FLIGHT_OWN if name in names)
    return Library("flight", tuple(names), tuple(units), np.column_stack(columns), own)


def contact_library(theta: np.ndarray, rate: np.ndarray, packed: np.ndarray) -> Library:
    """The contact terms delta^n and delta^n delta' (zero out of contact)."""
    delta = np.where(in_contact(theta, packed), penetration(theta, packed), 0.0)
    delta_dot = np.where(delta > 0.0, packed[P.SHAFT_L] * np.cos(theta) * rate, 0.0)
    names, units, columns = [], [], []
    for n in CONTACT_EXPONENTS:
        power = delta**n
        names += [f"delta^{n:g}", f"delta^{n:g} delta'"]
        units += [f"m^{n:g}", f"m^{n + 1:g}/s"]
        columns += [power, power * delta_dot]
    own = tuple(names.index(name) for name in CONTACT_OWN)
    return Library("contact", tuple(names), tuple(units), np.column_stack(columns), own,
                   most=CONTACT_MOST)


def select_terms(library: Library, residual: np.ndarray, blocks: np.ndarray,
                 least: int = MIN_SAMPLES) -> list[ProposedTerm]:
    """The terms of ``library`` that the residual acceleration asks for and that earn their
    place on held-out blocks (see the module's docstring), with their coefficients in
    theta'' per unit of the term."""
    ids = np.unique(blocks)
    if residual.size < least or ids.size < 4:
        return []
    scale = np.sqrt(np.mean(library.columns**2, axis=0))
    live = scale > 0
    x = np.where(live, library.columns / np.where(live, scale, 1.0), 0.0)
    y_scale = float(np.sqrt(np.mean(residual**2)))
    if not y_scale > 0:
        return []
    y = residual / y_scale
    sums = BlockSums.of(x, y, np.searchsorted(ids, blocks), ids.size)
    own = frozenset(j for j in library.own if live[j])
    candidates = live.copy()
    candidates[list(own)] = False
    odd = np.arange(ids.size) % 2 == 1
    sets = {frozenset()} | {s for fold in (~odd, odd)
                            for s in _stlsq_path(sums, fold, candidates, own)}
    best = min(sets, key=lambda s: (float(sums.heldout(own | s).sum()), len(s)))
    nothing = sums.heldout(own)
    tested = int(np.count_nonzero(candidates))
    t_needed = float(stats.t.isf(FALSE_ALARM / max(tested, 1), ids.size - 1))
    kept = set(best)
    while kept:
        with_all = sums.heldout(own | kept)
        worth = {j: _worth(sums.heldout(own | (kept - {j})), with_all, nothing)
                 for j in kept}
        failing = [j for j in kept if worth[j][0] < t_needed or worth[j][1] < MIN_GAIN]
        if not failing and (library.most is None or len(kept) <= library.most):
            break
        failing = failing or list(kept)
        kept.discard(min(failing, key=lambda j: worth[j][0]))
    if not kept:
        return []
    order = sorted(kept | own)
    coefficients, spread = sums.jackknife(order)
    half = float(stats.t.isf(0.025, ids.size - 1)) * spread
    out = []
    for i, j in enumerate(order):
        if j in own:
            continue
        unit_scale = y_scale / scale[j]
        value = coefficients[i] * unit_scale
        t_value, gain = worth[j]
        rivals = _rivals(sums, own, frozenset(kept), j, np.flatnonzero(candidates))
        out.append(ProposedTerm(
            term=library.names[j], region=library.region, coefficient=float(value),
            ci95=(float(value - half[i] * unit_scale), float(value + half[i] * unit_scale)),
            unit=f"rad/s^2 per {library.units[j]}", heldout_gain=gain, t=t_value,
            alternatives=tuple(library.names[k] for k in rivals)))
    return sorted(out, key=lambda term: -term.heldout_gain)


def _rivals(sums: BlockSums, own: frozenset[int], kept: frozenset[int], term: int,
            candidates: np.ndarray) -> list[int]:
    """The candidates that could stand in place of ``term`` among the ``kept``: swapped in
    for it, the held-out squares do not rise significantly (the paired log-ratio test over
    the blocks, one-sided at RIVAL_LEVEL) and they still gain MIN_GAIN over none of the
    two.  Over the swings of a decay theta'^3 and theta^2 theta' share their first
    harmonic and differ only in their third: a cubic damping's record was fitted by either,
    removing 69.30 and 69.38 % of the held-out squares."""
    others = kept - {term}
    with_term = sums.heldout(own | kept)
    without = sums.heldout(own | others)
    t_needed = float(stats.t.isf(RIVAL_LEVEL, sums.yy.size - 1))
    out = []
    for k in candidates:
        if k in kept:
            continue
        swapped = sums.heldout(own | others | {int(k)})
        t_value, _ = _worth(swapped, with_term, with_term)
        gain = float((without - swapped).sum() / without.sum())
        if t_value < t_needed and gain >= MIN_GAIN:
            out.append(int(k))
    return out


@dataclass(frozen=True)
class BlockSums:
    """Each block's x'x, x'y and y'y: every least-squares fit over any blocks and any terms,
    and its squares on any block, without going back to the samples."""

    xx: np.ndarray  # (blocks, terms, terms)
    xy: np.ndarray  # (blocks, terms)
    yy: np.ndarray  # (blocks,)

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray, block: np.ndarray, count: int) -> BlockSums:
        """The sums of samples ``x``, ``y`` in blocks numbered 0..count-1."""
        xx = np.zeros((count, x.shape[1], x.shape[1]))
        np.add.at(xx, block, x[:, :, None] * x[:, None, :])
        xy = np.zeros((count, x.shape[1]))
        np.add.at(xy, block, x * y[:, None])
        return cls(xx, xy, np.bincount(block, y * y, minlength=count))

    def fit(self, use: np.ndarray, terms: list[int]) -> np.ndarray:
        """Least-squares coefficients of ``terms`` over the blocks ``use`` (a mask)."""
        xx = self.xx[use].sum(axis=0)[np.ix_(terms, terms)]
        coefficients, *_ = np.linalg.lstsq(xx, self.xy[use].sum(axis=0)[terms], rcond=None)
        return coefficients

    def heldout(self, terms: frozenset[int]) -> np.ndarray:
        """Each block's sum of squares left by ``terms`` fitted on the other fold (blocks
        alternate between the two folds)."""
        odd = np.arange(self.yy.size) % 2 == 1
        out = self.yy.copy()
        if not terms:
            return out
        order = sorted(terms)
        for fold in (odd, ~odd):
            w = self.fit(~fold, order)
            xx = self.xx[fold][:, order][:, :, order]
            out[fold] += np.einsum("bij,i,j->b", xx, w, w) - 2.0 * self.xy[fold][:, order] @ w
        return out

    def jackknife(self, terms: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients over every block, and their standard errors by a delete-one-block
        jackknife (the residual acceleration is correlated over the smoother's window and
        the swings: whole blocks keep that honest)."""
        every = np.ones(self.yy.size, dtype=bool)
        leave = np.array([self.fit(every & (np.arange(self.yy.size) != b), terms)
                          for b in range(self.yy.size)])
        n = self.yy.size
        spread = np.sqrt((n - 1) / n * np.sum((leave - leave.mean(axis=0))**2, axis=0))
        return self.fit(every, terms), spread


def _stlsq_path(sums: BlockSums, use: np.ndarray, candidates: np.ndarray,
                own: frozenset[int]) -> list[frozenset[int]]:
    """The candidate term sets STLSQ keeps at each of THRESHOLDS on the blocks ``use``,
    the model's ``own`` terms fitted beside them unthresholded.

    The own terms are projected out of the normal equations (their Schur complement), and
    STLSQ runs on that least-squares problem compressed to a square one with the same
    normal equations (x'x = R'R, R w = z for x'y = R'z), so its cost does not grow with
    the samples."""
    # pysindy imports scikit-learn (about 2 s): only an analysis that ends unexplained pays it
    from pysindy.optimizers import STLSQ

    terms = np.flatnonzero(candidates)
    if terms.size == 0:
        return []
    fixed = sorted(own)
    total_xx = sums.xx[use].sum(axis=0)
    total_xy = sums.xy[use].sum(axis=0)
    xx = total_xx[np.ix_(terms, terms)]
    xy = total_xy[terms]
    if fixed:
        cross = total_xx[np.ix_(terms, fixed)]
        inverse = np.linalg.pinv(total_xx[np.ix_(fixed, fixed)])
        xx = xx - cross @ inverse @ cross.T
        xy = xy - cross @ inverse @ total_xy[fixed]
    eigenvalues, vectors = np.linalg.eigh(xx)
    root = np.sqrt(np.clip(eigenvalues, 0.0, None))
    kept = root > root.max() * 1e-8
    square = root[kept, None] * vectors[:, kept].T
    target = (vectors[:, kept].T @ xy) / root[kept]
    sets = []
    for threshold in THRESHOLDS:
        optimizer = STLSQ(threshold=threshold, alpha=RIDGE, max_iter=50, unbias=True)
        with warnings.catch_warnings():  # a threshold above every coefficient: the empty set
            warnings.simplefilter("ignore", UserWarning)
            optimizer.fit(square, target)
        sets.append(frozenset(int(j) for j in terms[np.flatnonzero(optimizer.ind_.ravel())]))
    return sets


def _worth(without: np.ndarray, with_all: np.ndarray,
           nothing: np.ndarray) -> tuple[float, float]:
    """What dropping a term costs on held-out blocks: the paired t-statistic of the log of
    each block's squares without it over its squares with it (a ratio, because blocks hold
    different numbers of a region's samples and residual sizes; its log, because a share
    of the squares is bounded by 1 above and not below: a cubic damping that removed
    80-95 % of most blocks' squares and added 50-70 % in two blocks where the residual
    crossed zero stood at t 4.9 on shares, 7 on logs), and the rise as a share of all the
    held-out squares with no term."""
    ratio = np.log(np.maximum(without, 1e-300) / np.maximum(with_all, 1e-300))
    spread = float(np.std(ratio, ddof=1)) / math.sqrt(ratio.size)
    t_value = float(ratio.mean() / spread) if spread > 0 else math.copysign(math.inf,
                                                                            ratio.mean())
    return t_value, float((without - with_all).sum() / nothing.sum())


def _widened(mask: np.ndarray, guard: int) -> np.ndarray:
    """``mask`` grown by ``guard`` samples either side."""
    out = mask.copy()
    for shift in range(1, guard + 1):
        out[shift:] |= mask[:-shift]
        out[:-shift] |= mask[shift:]
    return out
