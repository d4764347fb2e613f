"""Multiple shooting: fit a model to a long record as many short segments, each from its own
fitted initial state, linked by a continuity penalty.

One long simulation cannot follow a record whose start is uncertain, nor a chaotic one:
a small error in the initial state or a parameter grows until the fit sees only a
different trajectory.  Over a segment of a few drive periods the model's response to its
parameters stays smooth, so each segment gets its own (theta, theta') and the parameters
are shared; the penalty on the jump between a segment's end and the next one's start ties
the segments into one trajectory where the model allows it.

A segment may also run on past its fitted samples into samples it does not see: those are
forecasts from the fitted state, the held-out judge of a model.

Several records fitted with one set of shared parameters (the steps of a sweep: one rig,
each step its own drive) are one problem of several *parts*: the records laid end to end,
each part's segments run with that part's model (its ``packed_of``), no segment linked
across parts.  A parameter that enters one part's model alone (a step's drive phase) is a
``FreeParameter`` with that ``part``: its Jacobian column is zero outside the part, so the
columns of such parameters of different parts are differenced in one run together, as the
segment states are.

The solver is Levenberg-Marquardt on the joint vector (shared parameters, segment states).
Its Jacobian is a forward difference: one run per shared parameter, and two runs for all
segment states at once (a segment's samples depend only on its own state).  The runs are
compiled code that releases the GIL, so they go to threads.  The forward sensitivities
(:func:`analysis.simulate.sensitivity.segment_sensitivities`, read along their
linearised motion) were tried for these columns and cost more, not less: over 75
segments of a 30 s record with six parameters they took 8.4 plain runs (6.2 without the
graded contact steps), as many as the differences, and a two-cause analysis of a 10 Hz
record took 87 s against 76 s.

On heavy-tailed noise the data residuals go through a robust (soft L1) loss: each
becomes the signed square root of its loss, so that half the sum of squares is the
robust cost and the same solver minimises it; a spike then pulls on the fit like a few
noise sigmas, not like its square.  The continuity jumps stay quadratic.
"""

from __future__ import annotations

import copy
import functools
import math
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from itertools import pairwise
from typing import NamedTuple

import numpy as np
import scipy.sparse as sparse
from scipy.sparse.linalg import splu

from analysis.extensions import coordinate_matrix
from analysis.identify.intervals import Z95, correlation_time
from analysis.identify.preprocess import sample_detail
from analysis.identify.result import Estimate, Residuals
from analysis.identify.threads import blas_on_one_thread
from analysis.simulate.segments import integrate_segments

# The runs' tolerances: the runs' own error must stay far below any rig's noise, or it
# moves the fitted values and narrows their intervals; 1e-7 of a swing of ~0.1 rad is
# 1e-8 rad.
RTOL = 1e-7
ATOL = 1e-9
MAX_ITERATIONS = 40
# After a fit converges, segments stuck on a motion their predecessor's end does not
# continue take that continuation when it lowers their cost by more than REPAIR_GAIN (in
# chi^2 / 2: a few samples' worth against a wrong basin's hundreds), over up to
# REPAIR_PASSES passes; the fit then goes on for REPAIR_ITERATIONS, REPAIR_ROUNDS times
# at most.
REPAIR_GAIN = 10.0
REPAIR_PASSES = 12
REPAIR_ROUNDS = 1
REPAIR_ITERATIONS = 6  # the fit's further iterations after a repair
MAX_STEPS_PER_SEGMENT = 20_000  # a few hundred suffice; a trial needing more fails
COST_TOLERANCE = 0.05  # a step gaining less chi^2 / 2 than this changes no judgement
# ... nor does a gain this small relative to the cost above the noise's own (chi^2 / 2 of
# half a unit a sample): it matters on a model that misses the record by far, never on one
# at the noise, where parameter intervals are read
RELATIVE_TOLERANCE = 1e-4
FAILED_RESIDUAL = 1e3  # in noise units, for samples a stopped run did not reach
# Scale c of the soft-L1 loss rho(r) = 2 c^2 (sqrt(1 + (r / c)^2) - 1), in noise units.
# A location fit's asymptotic variance E[psi^2] / E[psi']^2 (psi = rho' / 2) under
# Student-t noise of 3, 2.25 and 1.5 degrees of freedom scaled to the Gaussian's median
# size (the heavy tails of the reference records) is 1.43, 1.62, 2.05 at c = 3, against
# least squares' 2.33, 6.4 and infinity (Cramer-Rao bounds 1.17, 1.15, 1.08); on Gaussian
# noise c = 3 keeps 99 % of least squares' efficiency.  A smaller c is nearer the bound
# in theory, but on forced records it lets the contact parameters settle in other basins:
# over 11 heavy-tailed 20 s reference records c = 1, 2, 3 left the truth outside the 95 %
# intervals in 20, 8, 3 of 66 cases (stiffness off by 9.9, 5.6, 4.0 % rms).
ROBUST_SCALE = 3.0


def _gaussian_mean(f: Callable[[np.ndarray], np.ndarray]) -> float:
    """E[f(e)] for standard normal e (Gauss-Hermite quadrature: the smooth integrands here
    to rounding)."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(120)
    return float(weights @ f(nodes) / math.sqrt(2.0 * math.pi))


def _spread(r: np.ndarray) -> np.ndarray:
    """s = sqrt(1 + (r / c)^2) of noise-unit residuals: the soft-L1 loss is 2 c^2 (s - 1),
    its psi = r / s and psi' = s^-3."""
    z = r / ROBUST_SCALE
    return np.sqrt(1.0 + z * z)


def robust_residuals(r: np.ndarray) -> np.ndarray:
    """Noise-unit residuals as signed square roots of their soft-L1 loss, r sqrt(2 / (1 + s))
    (no cancellation near 0): half their sum of squares is the robust cost."""
    return r * np.sqrt(2.0 / (1.0 + _spread(r)))


def psi_of(r: np.ndarray) -> np.ndarray:
    """psi = rho' / 2 = r / s of the soft-L1 loss: a residual's pull on the fit."""
    return r / _spread(r)


def robust_slope(r: np.ndarray) -> np.ndarray:
    """d robust_residuals / d r = sqrt((1 + s) / 2) / s: a data row's Jacobian factor."""
    s = _spread(r)
    return np.sqrt(0.5 * (1.0 + s)) / s


# A perfect model's residual variance in the robust intervals' sense, E[psi^2] / E[psi'],
# on Gaussian noise: the floor of the intervals' scale, as 1 is least squares'.
ROBUST_GAUSSIAN_SCALE = (_gaussian_mean(lambda e: (e / _spread(e)) ** 2)
                         / _gaussian_mean(lambda e: _spread(e) ** -3.0))

PackedOf = Callable[[Mapping[str, float]], np.ndarray]
# (values, times, true angle, rate at the first time) -> measured angle, for one stretch of
# contiguous samples (or for all samples at once, the rate None, when it has no memory)
Measure = Callable[[Mapping[str, float], np.ndarray, np.ndarray, float | None], np.ndarray]


@dataclass(frozen=True)
class FreeParameter:
    """A shared parameter the fit adjusts: start value, finite-difference step (in log units
    when ``log``), and bounds."""

    name: str
    start: float
    step: float
    log: bool = False
    lower: float = -math.inf
    upper: float = math.inf
    part: int | None = None  # the one part whose model it enters (None: every part's)
    # another free parameter and a coefficient: the fit's coordinate of this one is its own
    # plus that times the other's (:attr:`analysis.extensions.ParameterPlan.tie`)
    tie: tuple[str, float] | None = None


@dataclass(frozen=True)
class Segments:
    """How a record is cut: segment k starts at sample ``start[k]`` (its state is fitted
    there), is fitted to samples ``start[k]:fit_stop[k]``, forecasts ``fit_stop[k]:stop[k]``
    and ends at time ``end_s[k]``; when ``linked[k]`` its end state is compared with
    segment k+1's start state."""

    start: np.ndarray
    fit_stop: np.ndarray
    stop: np.ndarray
    end_s: np.ndarray
    linked: np.ndarray

    @property
    def count(self) -> int:
        """Number of segments."""
        return int(self.start.size)

    def fit_mask(self, n: int) -> np.ndarray:
        """Samples some segment is fitted to."""
        return _cover(n, self.start, self.fit_stop)

    def forecast_mask(self, n: int) -> np.ndarray:
        """Samples some segment forecasts without seeing them."""
        return _cover(n, self.fit_stop, self.stop)


def _cover(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    mark = np.zeros(n + 1, dtype=np.int64)
    np.add.at(mark, a, 1)
    np.add.at(mark, b, -1)
    return np.cumsum(mark[:-1]) > 0


def cut_segments(
    t: np.ndarray, first_s: float, length_s: float, *, heldout_s: float = 0.0
) -> Segments:
    """Contiguous linked segments from ``first_s`` on, each ``length_s`` fitted and then
    ``heldout_s`` forecast; the record's last partial segment is kept if it is at least half
    a segment long."""
    dt = float(t[1] - t[0])
    span = length_s + heldout_s
    starts_s = np.arange(first_s, t[-1] - 0.5 * length_s, span)
    start = np.searchsorted(t, starts_s - 0.5 * dt)
    start = np.unique(start[start < t.size - 2])
    if start.size == 0:
        raise ValueError(f"record of {t[-1] - t[0]:.3g} s is shorter than one segment")
    stop = np.append(start[1:], t.size)
    fit_stop = np.minimum(np.searchsorted(t, t[start] + length_s - 0.5 * dt), stop)
    fit_stop = np.maximum(fit_stop, start + 1)
    end_s = np.append(t[start[1:]], t[-1])
    linked = np.append(np.ones(start.size - 1, dtype=bool), False)
    return Segments(start, fit_stop, stop, end_s, linked)


@dataclass(frozen=True)
class ShootingFit(Residuals):
    """A multiple-shooting fit: shared values, segment states, and what they predict."""

    values: dict[str, float]
    states: np.ndarray  # (segments, 2): theta, theta' at each segment's start
    estimates: dict[str, Estimate]  # the free shared parameters with 95 % intervals
    prediction: np.ndarray  # measured angle the model gives, NaN where no segment runs
    rate: np.ndarray  # the model's true angular rate there [rad/s]
    true_angle: np.ndarray  # the model's true angle there (before the sensor) [rad]
    residual: np.ndarray  # prediction - data on fitted valid samples, NaN elsewhere
    forecast_residual: np.ndarray  # prediction - data on held-out valid samples, NaN elsewhere
    jumps: np.ndarray  # (links, 2): end state - next start state of linked segments
    n_params: int
    success: bool
    message: str
    iterations: int
    correlation: np.ndarray | None = None  # of the free shared parameters, same order

    @property
    def forecast_rms(self) -> float:
        """RMS error of the forecasts over the held-out samples [rad] (nan without any)."""
        r = self.forecast_residual[np.isfinite(self.forecast_residual)]
        return float(math.sqrt(np.mean(r * r))) if r.size else math.nan


class _Solution(NamedTuple):
    """Where Levenberg-Marquardt stopped: step-unit values, segment states, the residual
    vector and the run behind it, and how it ended."""

    u: np.ndarray
    s: np.ndarray
    r: np.ndarray
    theta: np.ndarray
    ends: np.ndarray
    success: bool
    message: str
    iterations: int


class _Times:
    """The times a run reports, segment by segment: ``out_t[bounds[k]:bounds[k + 1]]`` for
    segment k (its last time is where it ends), and the groups of segments run in threads
    (each within one part: a part's segments run with its own model)."""

    def __init__(self, out_t: np.ndarray, bounds: np.ndarray, threads: int,
                 part_of_segment: np.ndarray) -> None:
        self.out_t = out_t
        self.bounds = bounds
        sizes = np.diff(bounds)
        self.parts = _part_ranges(part_of_segment)  # each part's segments, run whole
        self.groups = []
        for a, b in self.parts:
            self.groups += [(a + lo, a + hi) for lo, hi in _groups(sizes[a:b], threads)]


def _part_ranges(part_of_segment: np.ndarray) -> list[tuple[int, int]]:
    """[first, stop) segment ranges of the parts, in order."""
    cuts = np.flatnonzero(np.diff(part_of_segment)) + 1
    edges = np.concatenate([[0], cuts, [part_of_segment.size]])
    return [(int(a), int(b)) for a, b in pairwise(edges)]


class _Jacobian(NamedTuple):
    """The shooting Jacobian by its structure: dense shared columns, and each segment's two
    state columns seen by its own data rows and by the continuity rows of the links into
    and out of it.  Its normal equations are summed from that structure: a general sparse
    product spent more time than the runs of the columns on 2 cores."""

    shared: np.ndarray  # (rows, g)
    data_state: np.ndarray  # (2, data rows): d row / d own segment's state k
    segment_of_row: np.ndarray  # (data rows,)
    links: np.ndarray  # segments whose end links to the next one's start
    link_state: np.ndarray  # (links, 2, 2): d jump c / d linked segment's state k
    link_next: np.ndarray  # (2,): d jump c / d next segment's state c
    n_seg: int

    def normal_matrix(self, row_scale: np.ndarray | None = None) -> sparse.csc_matrix:
        """J^T J (of diag(row_scale) J when given), sparse: shared block, border and
        block-tridiagonal states."""
        g, n, rows = self.shared.shape[1], self.n_seg, self.data_state.shape[1]
        p, d, e = self.shared, self.data_state, self.link_state
        nxt = np.broadcast_to(self.link_next, (self.links.size, 2))
        if row_scale is not None:
            p = p * row_scale[:, None]
            d = d * row_scale[:rows]
            link_scale = row_scale[rows:].reshape(-1, 2)
            e = e * link_scale[:, :, None]
            nxt = nxt * link_scale
        seg, a, b = self.segment_of_row, self.links, self.links + 1
        border = np.zeros((g, n, 2))  # shared x state
        for k in range(2):
            for i in range(g):
                border[i, :, k] = np.bincount(seg, p[:rows, i] * d[k], minlength=n)
        p_links = p[rows:].reshape(self.links.size, 2, g)  # (links, c, g)
        border[:, a, :] += np.einsum("jcg,jck->gjk", p_links, e)
        border[:, b, :] += np.einsum("jcg,jc->gjc", p_links, nxt)
        diagonal = np.zeros((n, 2, 2))
        for k, m in ((0, 0), (0, 1), (1, 1)):
            diagonal[:, k, m] = np.bincount(seg, d[k] * d[m], minlength=n)
        diagonal[:, 1, 0] = diagonal[:, 0, 1]
        diagonal[a] += np.einsum("jck,jcm->jkm", e, e)
        diagonal[b, 0, 0] += nxt[:, 0] ** 2
        diagonal[b, 1, 1] += nxt[:, 1] ** 2
        coupling = e * nxt[:, :, None]  # (links, c, k): state k of a with state c of b
        state = g + 2 * np.arange(n)
        rows_, cols_, vals_ = [], [], []

        def put(r_: np.ndarray, c_: np.ndarray, v_: np.ndarray, mirror: bool) -> None:
            rows_.append(r_.ravel())
            cols_.append(c_.ravel())
            vals_.append(v_.ravel())
            if mirror:
                rows_.append(c_.ravel())
                cols_.append(r_.ravel())
                vals_.append(v_.ravel())

        gi = np.arange(g)
        put(np.repeat(gi, g), np.tile(gi, g), p.T @ p, False)
        kk = np.arange(2)
        put(np.broadcast_to(gi[:, None, None], border.shape),
            np.broadcast_to(state[None, :, None] + kk, border.shape), border, True)
        put(np.broadcast_to((state[:, None] + kk)[:, :, None], diagonal.shape),
            np.broadcast_to((state[:, None] + kk)[:, None, :], diagonal.shape), diagonal, False)
        put(np.broadcast_to((state[a][:, None] + kk)[:, None, :], coupling.shape),
            np.broadcast_to((state[b][:, None] + kk)[:, :, None], coupling.shape), coupling,
            True)
        size = g + 2 * n
        return sparse.csc_matrix((np.concatenate(vals_), (np.concatenate(rows_),
                                  np.concatenate(cols_))), shape=(size, size))

    def toarray(self) -> np.ndarray:
        """J itself, dense (to look at it: the fit uses only its normal equations)."""
        g, rows = self.shared.shape[1], self.data_state.shape[1]
        out = np.zeros((self.shared.shape[0], g + 2 * self.n_seg))
        out[:, :g] = self.shared
        for k in range(2):
            out[np.arange(rows), g + 2 * self.segment_of_row + k] = self.data_state[k]
            for c in range(2):
                link_rows = rows + 2 * np.arange(self.links.size) + c
                out[link_rows, g + 2 * self.links + k] = self.link_state[:, c, k]
        for c in range(2):
            link_rows = rows + 2 * np.arange(self.links.size) + c
            out[link_rows, g + 2 * (self.links + 1) + c] = self.link_next[c]
        return out

    def gradient(self, r: np.ndarray) -> np.ndarray:
        """J^T r."""
        g, n, rows = self.shared.shape[1], self.n_seg, self.data_state.shape[1]
        out = np.zeros(g + 2 * self.n_seg)
        out[:g] = self.shared.T @ r
        states = out[g:].reshape(n, 2)
        for k in range(2):
            states[:, k] = np.bincount(self.segment_of_row, self.data_state[k] * r[:rows],
                                       minlength=n)
        r_links = r[rows:].reshape(-1, 2)
        states[self.links] += np.einsum("jck,jc->jk", self.link_state, r_links)
        states[self.links + 1] += self.link_next * r_links
        return out


class ShootingProblem:
    """The record, its segments and the model (as functions of the shared values)."""

    def __init__(
        self,
        t: np.ndarray,
        y: np.ndarray,
        valid: np.ndarray,
        noise_rad: float,
        segments: Segments,
        packed_of: PackedOf | Sequence[PackedOf],
        free: list[FreeParameter],
        fixed: Mapping[str, float],
        *,
        part_of_segment: np.ndarray | None = None,
        measure: Measure | None = None,
        measure_has_memory: bool = True,
        rate_scale: float = 1.0,
        threads: int | None = None,
        robust: bool = False,
    ) -> None:
        self.t = np.asarray(t, dtype=float)
        self.y = np.asarray(y, dtype=float)
        self.valid = np.asarray(valid, dtype=bool) & np.isfinite(self.y)
        self.sigma = float(noise_rad)
        if not self.sigma > 0:
            raise ValueError(f"noise_rad = {noise_rad!r}: must be > 0")
        self.segments = segments
        # the parts: one model (packed_of) per part, each segment in one part
        self.packs = list(packed_of) if isinstance(packed_of, Sequence) else [packed_of]
        self.part_of_segment = (np.zeros(segments.count, dtype=np.int64)
                                if part_of_segment is None
                                else np.asarray(part_of_segment, dtype=np.int64))
        _check_parts(segments, self.part_of_segment, len(self.packs))
        self.measure = measure
        # a sensor without memory (a zero, a cubic) reads all samples in one call; one with
        # memory (a filter) reads each chain of linked segments as one stretch
        self.measure_has_memory = measure_has_memory
        self.free = list(free)
        # each parameter's coordinate (its value, or its log) at the start, and the map from
        # step units to the coordinates' offsets (a tied parameter moves with its partner)
        self.origin = np.array([math.log(p.start) if p.log else p.start for p in self.free])
        self.coordinates = coordinate_matrix([p.name for p in self.free],
                                             [p.step for p in self.free],
                                             [p.tie for p in self.free])
        self.fixed = dict(fixed)
        self.rate_scale = float(rate_scale)  # theta' jumps count as theta jumps times this
        self.threads = thread_count(threads)
        self.robust = robust  # the data residuals through the soft-L1 loss
        s = segments
        # sample times of all segments back to back, each followed by its end time
        pieces, bounds = [], [0]
        for a, b, end in zip(s.start, s.stop, s.end_s, strict=True):
            pieces.append(self.t[a:b])
            pieces.append([end])
            bounds.append(bounds[-1] + (b - a) + 1)
        self.out_t = np.concatenate(pieces)
        self.bounds = np.asarray(bounds, dtype=np.int64)
        self.sample_of = np.concatenate([np.arange(a, b) for a, b in zip(s.start, s.stop,
                                                                          strict=True)])
        self.segment_of = np.repeat(np.arange(s.count), s.stop - s.start)
        self.times = _Times(self.out_t, self.bounds, self.threads, self.part_of_segment)
        self.is_end = np.zeros(self.out_t.size, dtype=bool)
        self.is_end[self.bounds[1:] - 1] = True
        fit = np.zeros(self.sample_of.size, dtype=bool)
        offset = 0
        for a, f, b in zip(s.start, s.fit_stop, s.stop, strict=True):
            fit[offset:offset + f - a] = True
            offset += b - a
        self.fitted = fit & self.valid[self.sample_of]  # rows of the data residual
        self.links = np.flatnonzero(s.linked[:-1]) if s.count > 1 else np.zeros(0, np.int64)
        # the part of each residual row (data rows, then two per link)
        self.row_part = np.concatenate([
            self.part_of_segment[self.segment_of[self.fitted]],
            np.repeat(self.part_of_segment[self.links], 2)])
        for p in self.free:
            if p.part is not None and not 0 <= p.part < len(self.packs):
                raise ValueError(f"free parameter {p.name}: part {p.part}; the problem has "
                                 f"{len(self.packs)}")
        # chains of linked segments: the measurement runs over each as one stretch (a
        # filter's memory carries across a link, not across a gap)
        heads = np.concatenate([[0], np.flatnonzero(~s.linked[:-1]) + 1])
        rows = self.bounds - np.arange(s.count + 1)  # segment starts among sample rows
        tails = np.append(heads[1:], s.count)
        self.chains = [(int(rows[h]), int(rows[e]), int(self.bounds[h]))
                       for h, e in zip(heads, tails, strict=True)]

    # ------------------------------------------------------------------ model evaluation

    def packed_of(self, values: Mapping[str, float]) -> list[np.ndarray]:
        """Every part's packed model at ``values``."""
        return [pack(values) for pack in self.packs]

    def values_of(self, u: np.ndarray) -> dict[str, float]:
        """Shared values at the step-unit vector ``u``."""
        out = dict(self.fixed)
        coordinates = self.origin + self.coordinates @ np.asarray(u, dtype=float)
        for p, x in zip(self.free, coordinates.tolist(), strict=True):
            value = math.exp(x) if p.log else x
            # a tied parameter's box in step units holds at its partner's start only
            out[p.name] = min(max(value, p.lower), p.upper) if p.tie else value
        return out

    def _integrate(self, values: Mapping[str, float], states: np.ndarray,
                   split: bool, times: _Times | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Angle and rate at every segment time (ends included), or at ``times`` instead
        (each segment's own, its last where it ends).  ``split`` runs groups of segments in
        threads (they are independent, so the result is the same to the bit): a trial
        step's run is otherwise one core's work while the others wait.  Unsplit, each part
        runs whole (with its own model) in the calling thread."""
        p = self.packed_of(values)
        part = self.part_of_segment
        starts = self.t[self.segments.start]
        at = times or self.times
        groups = at.groups if split else at.parts

        def group(bounds: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
            a, b = bounds
            lo, hi = at.bounds[a], at.bounds[b]
            th, om, _ = integrate_segments(p[part[a]], starts[a:b], states[a:b], at.out_t[lo:hi],
                                           at.bounds[a:b + 1] - lo, rtol=RTOL, atol=ATOL,
                                           max_steps=MAX_STEPS_PER_SEGMENT)
            return th, om

        if len(groups) == 1:
            return group(groups[0])
        pool = _pool(self.threads, "shooting-run") if split else _InCaller()
        parts = list(pool.map(group, groups))
        return (np.concatenate([th for th, _ in parts]),
                np.concatenate([om for _, om in parts]))

    def run(self, values: Mapping[str, float], states: np.ndarray, *,
            split: bool = True) -> tuple[np.ndarray, ...]:
        """Measured angle at every segment sample, and every segment's end state (``split``:
        see ``_integrate``; a Jacobian's columns, already in threads, run whole)."""
        return self.read(values, *self._integrate(values, states, split))

    def read(self, values: Mapping[str, float], th: np.ndarray, om: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """``run``'s output from the model's motion at every segment time (``_integrate``):
        what the sensor reports with ``values`` at the samples, and the end states."""
        ends = np.column_stack([th[self.is_end], om[self.is_end]])
        theta = th[~self.is_end]
        if self.measure is not None and not self.measure_has_memory:
            theta = self.measure(values, self.t[self.sample_of], theta, None)
        elif self.measure is not None:
            times = self.t[self.sample_of]
            theta = np.concatenate([
                self.measure(values, times[a:b], theta[a:b], float(om[first]))
                for a, b, first in self.chains
            ])
        return theta, ends

    def motion(self, values: Mapping[str, float], states: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """The model's true angle and rate at every segment sample (no sensor applied)."""
        th, om = self._integrate(values, states, split=True)
        return th[~self.is_end], om[~self.is_end]

    def residuals(self, theta: np.ndarray, ends: np.ndarray, states: np.ndarray) -> np.ndarray:
        """Noise-scaled data residuals of the fitted rows (through the robust loss when the
        problem is robust), then the continuity jumps."""
        r = self._data_residuals(theta)
        if self.robust:
            r = robust_residuals(r)
        jumps = (ends[self.links] - states[self.links + 1]) / np.array(
            [self.sigma, self.sigma * self.rate_scale]
        )
        jumps = np.where(np.isfinite(jumps), jumps, FAILED_RESIDUAL)
        return np.concatenate([r, jumps.ravel()])

    def _data_residuals(self, theta: np.ndarray) -> np.ndarray:
        """Noise-scaled residuals of the fitted rows, FAILED_RESIDUAL where a run stopped."""
        r = (theta[self.fitted] - self.y[self.sample_of[self.fitted]]) / self.sigma
        return np.where(np.isfinite(r), r, FAILED_RESIDUAL)

    def _noise_loss(self) -> float:
        """The robust loss a perfect model leaves per fitted sample, E[rho(noise)], from the
        record's detail (the noise with the motion's curvature gone, sqrt(6) times its
        size): a spike there counts up to 1.6 times what it does in the residual (it shows
        in three details), so heavy tails make this an upper bound, and the stop rule
        stricter rather than looser (5-24 % above the noise's own on reference records)."""
        finite = self.y[self.valid]
        detail = sample_detail(finite) / (math.sqrt(6.0) * self.sigma)
        return float(np.mean(robust_residuals(detail) ** 2))

    # ------------------------------------------------------------------ the fit

    def fit_states(
        self, states0: np.ndarray, values: Mapping[str, float] | None = None, *,
        state_steps: tuple[float, float] = (1e-6, 1e-6),
        horizons: tuple[float, ...] = (0.25, 0.5, 1.0), iterations: int = 8,
    ) -> np.ndarray:
        """Each segment's start state fitted alone with the shared values held (their starts
        unless given): over the first quarter of its samples, then half, then all, so that a
        rough start (a smoothed derivative) is drawn onto the data before the model's
        sensitivity to it grows.  Segments are independent here: no continuity."""
        values = dict(values) if values is not None else self.values_of(np.zeros(len(self.free)))
        hs = np.asarray(state_steps, dtype=float)
        s = np.asarray(states0, dtype=float).copy()
        n_seg = self.segments.count
        seg_rows = self.segment_of
        position = np.arange(self.sample_of.size) - np.repeat(
            self.bounds[:-1] - np.arange(n_seg), self.segments.stop - self.segments.start)
        length = (self.segments.fit_stop - self.segments.start)[seg_rows]
        y = self.y[self.sample_of]
        # without a sensor memory linking segments, the readings of a mix of two runs' states
        # are those runs' readings, segment by segment: no run is needed to combine them
        independent = self.measure is None or not self.measure_has_memory

        def segment_costs(theta: np.ndarray, use: np.ndarray) -> np.ndarray:
            r = np.where(use, (theta - y) / self.sigma, 0.0)
            r = np.where(np.isfinite(r), r, FAILED_RESIDUAL)
            return np.bincount(seg_rows, r * r, minlength=n_seg), r

        for horizon in horizons:
            within = position < np.maximum(horizon * length, 8)
            use = self.fitted & within
            # a sensor without memory reads a sample from the motion up to it alone, so the
            # runs stop at the horizon (the same numbers: the steps do not depend on where
            # the outputs are)
            times = None
            if independent and not within.all():
                kept = np.bincount(seg_rows[within], minlength=n_seg)
                times = _Times(self.t[self.sample_of[within]],
                               np.concatenate([[0], np.cumsum(kept)]), self.threads,
                               self.part_of_segment)

            def readings(states: np.ndarray, within: np.ndarray = within,
                         times: _Times | None = times) -> np.ndarray:
                """The sensor's readings from segments started at ``states`` (NaN past
                the horizon when the runs stop there)."""
                if times is None:
                    return self.run(values, states)[0]
                th, _ = self._integrate(values, states, True, times)
                if self.measure is not None:
                    th = self.measure(values, times.out_t, th, None)
                out = np.full(self.sample_of.size, np.nan)
                out[within] = th
                return out

            lam = np.full(n_seg, 1e-3)
            theta = readings(s)
            cost, r = segment_costs(theta, use)
            for _ in range(iterations):
                cols = []
                for k in range(2):
                    ds = s.copy()
                    ds[:, k] += hs[k]
                    th = readings(ds)
                    d = np.where(use, (th - theta) / self.sigma, 0.0)
                    cols.append(np.where(np.isfinite(d), d, 0.0))
                a00 = np.bincount(seg_rows, cols[0] ** 2, minlength=n_seg)
                a01 = np.bincount(seg_rows, cols[0] * cols[1], minlength=n_seg)
                a11 = np.bincount(seg_rows, cols[1] ** 2, minlength=n_seg)
                g0 = np.bincount(seg_rows, cols[0] * r, minlength=n_seg)
                g1 = np.bincount(seg_rows, cols[1] * r, minlength=n_seg)
                for _attempt in range(6):
                    d00 = a00 * (1 + lam) + 1e-12
                    d11 = a11 * (1 + lam) + 1e-12
                    det = d00 * d11 - a01 * a01
                    step0 = -(d11 * g0 - a01 * g1) / det
                    step1 = -(d00 * g1 - a01 * g0) / det
                    trial = s + np.column_stack([step0, step1]) * hs
                    th = readings(trial)
                    new_cost, _new_r = segment_costs(th, use)
                    better = new_cost < cost
                    s[better] = trial[better]
                    lam = np.where(better, lam / 3.0, lam * 4.0)
                    if better.any():
                        if independent:  # each segment's reading is its own run's
                            theta = np.where(better[seg_rows], th, theta)
                        else:
                            theta = readings(s)
                        cost, r = segment_costs(theta, use)
                        break
        return s

    def fit(
        self, states0: np.ndarray, *, max_iterations: int = MAX_ITERATIONS,
        state_steps: tuple[float, float] = (1e-6, 1e-6),
    ) -> ShootingFit:
        """Levenberg-Marquardt from the free parameters' starts and the given segment states
        (states taken from elsewhere, and after convergence, repaired where a segment's
        predecessor continues into a better fit: ``_continued_states``).

        A robust problem is first solved by least squares, and the robust loss takes over
        from there (each with ``max_iterations``): least squares finds the basin, where
        the robust loss started cold can settle on a motion that misses some impacts and
        writes them off as outliers (over 11 heavy-tailed reference records the stiffness
        came out 11.5 % rms off from a cold start, 4.0 % from least squares' optimum)."""
        hs = np.asarray(state_steps, dtype=float)
        lower, upper = self._bounds()
        u = np.clip(np.zeros(len(self.free)), lower, upper)
        s = np.asarray(states0, dtype=float).copy()
        iterations = 0
        if self.robust:
            plain = copy.copy(self)
            plain.robust = False
            basin = plain._solve(u, s, hs, max_iterations)
            u, s, iterations = basin.u, basin.s, basin.iterations
        done = self._solve(u, s, hs, max_iterations)
        return self._result(done.u, done.s, done.r, done.theta, done.ends, hs, done.success,
                            done.message, iterations + done.iterations)

    def _solve(self, u: np.ndarray, s: np.ndarray, hs: np.ndarray,
               max_iterations: int) -> _Solution:
        """The Levenberg-Marquardt iterations of ``fit`` from step-unit values ``u`` and
        segment states ``s``."""
        g = len(self.free)
        n_seg = self.segments.count
        lower, upper = self._bounds()
        # one iteration moves a log-scale parameter by at most a factor e
        max_move = np.array([1.0 / p.step if p.log else math.inf for p in self.free])

        def evaluate(u_, s_):
            values = self.values_of(u_)
            motion = self._integrate(values, s_, True)
            theta, ends = self.read(values, *motion)
            return self.residuals(theta, ends, s_), theta, ends, motion

        r, theta, ends, motion = evaluate(u, s)
        repaired = self._continued_states(self.values_of(u), s, motion)  # states from elsewhere
        if repaired is not None:
            s = repaired
            r, theta, ends, motion = evaluate(u, s)
        cost = 0.5 * float(r @ r)
        noise_cost = 0.5 * float(np.count_nonzero(self.fitted))  # a perfect model's, expected
        if self.robust:
            noise_cost *= self._noise_loss()
        lam = 1e-3
        nu = 2.0
        message = "maximum iterations reached"
        success = False
        iterations = 0
        budget = max_iterations
        for repair_round in range(REPAIR_ROUNDS + 1):
            small_before = False
            for _ in range(budget):
                iterations += 1
                jac = self._jacobian(u, s, r, theta, ends, hs, motion)
                a = jac.normal_matrix()
                grad = jac.gradient(r)
                diag = a.diagonal()
                diag = np.maximum(diag, 1e-12 * max(1.0, float(np.max(diag))))
                improved = False
                for _ in range(12):
                    try:
                        step = -splu((a + sparse.diags(lam * diag)).tocsc()).solve(grad)
                    except RuntimeError:  # singular
                        lam *= nu
                        nu *= 2.0
                        continue
                    if not np.all(np.isfinite(step)):
                        lam *= nu
                        nu *= 2.0
                        continue
                    u_new = np.clip(u + np.clip(step[:g], -max_move, max_move), lower, upper)
                    s_new = s + step[g:].reshape(n_seg, 2) * hs
                    try:
                        r_new, theta_new, ends_new, motion_new = evaluate(u_new, s_new)
                        cost_new = 0.5 * float(r_new @ r_new)
                    except (ValueError, OverflowError, ZeroDivisionError):
                        cost_new = math.inf  # a trial outside the model's domain: rejected
                    predicted = -(grad @ step) - 0.5 * step @ (a @ step)
                    rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
                    if cost_new < cost:
                        gain = cost - cost_new
                        u, s, r, theta, ends = u_new, s_new, r_new, theta_new, ends_new
                        motion = motion_new
                        cost = cost_new
                        lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                        nu = 2.0
                        improved = True
                        break
                    lam *= nu
                    nu *= 2.0
                if not improved:
                    message = "no step lowers the cost"
                    success = True
                    break
                small = gain <= max(COST_TOLERANCE, RELATIVE_TOLERANCE * (cost - noise_cost))
                if small and (lam < 1e-2 or small_before):
                    message = "cost converged"
                    success = True
                    break
                small_before = small
            if repair_round == REPAIR_ROUNDS:
                break
            repaired = self._continued_states(self.values_of(u), s, motion)
            if repaired is None:
                break
            s = repaired
            r, theta, ends, motion = evaluate(u, s)
            cost = 0.5 * float(r @ r)
            lam, nu = 1e-3, 2.0
            budget = REPAIR_ITERATIONS
        return _Solution(u, s, r, theta, ends, success, message, iterations)

    def _continued_states(
        self, values: Mapping[str, float], s: np.ndarray,
        motion: tuple[np.ndarray, np.ndarray],
    ) -> np.ndarray | None:
        """Segment states with each segment that sits in a worse basin than its
        predecessor's motion continued replaced by that continuation, or None when none is.

        A segment's state is a local fit: after an impact near grazing it can settle on a
        motion the record does not show while its predecessor's end is on the right one.
        Two models compared on the same record must not differ by such accidents.  A
        segment takes its predecessor's end state when that lowers its own cost (its data,
        the jump into it and the jump out of it) by more than REPAIR_GAIN; a segment whose
        predecessor changed waits for the next pass, and passes repeat (a good motion
        continues along a run of bad segments) up to REPAIR_PASSES times.  ``motion`` is
        the model's motion at (values, s) (``_integrate``), which the caller has."""
        if self.links.size == 0:
            return None
        n_seg = self.segments.count
        rows = int(np.count_nonzero(self.fitted))
        seg_rows = self.segment_of[self.fitted]
        scale = np.array([self.sigma, self.sigma * self.rate_scale])

        def local_costs(r_: np.ndarray, own: np.ndarray, ends_: np.ndarray,
                        successors: np.ndarray, into: np.ndarray) -> np.ndarray:
            """Each segment's data cost plus the jumps into it (from its predecessor's end
            in ``into`` to its ``own`` start) and out of it (to ``successors``' starts)."""
            data = np.bincount(seg_rows, r_[:rows] ** 2, minlength=n_seg)
            out = np.zeros(n_seg)
            jump_out = np.sum(((ends_[self.links] - successors[self.links + 1]) / scale) ** 2,
                              axis=1)
            out[self.links] += jump_out
            jump_in = np.sum(((into[self.links] - own[self.links + 1]) / scale) ** 2, axis=1)
            out[self.links + 1] += jump_in
            return 0.5 * (data + out)

        changed = False
        theta_s, ends_s = self.read(values, *motion)
        r_s = self.residuals(theta_s, ends_s, s)
        for _ in range(REPAIR_PASSES):
            trial = s.copy()
            continued = self.links[np.all(np.isfinite(ends_s[self.links]), axis=1)]
            trial[continued + 1] = ends_s[continued]  # a run that stopped continues nothing
            theta_t, ends_t = self.run(values, trial)
            r_t = self.residuals(theta_t, ends_t, trial)
            now = local_costs(r_s, s, ends_s, s, ends_s)
            # a trial segment starts on its predecessor's present end (no jump in) and
            # jumps out to its successor's present state
            then = local_costs(r_t, trial, ends_t, s, ends_s)
            better = np.zeros(n_seg, dtype=bool)
            better[self.links + 1] = (now - then)[self.links + 1] > REPAIR_GAIN
            for k in np.flatnonzero(better):  # no two neighbours change in one pass
                if k > 0 and better[k - 1]:
                    better[k] = False
            if not better.any():
                break
            s = np.where(better[:, None], trial, s)
            changed = True
            theta_s, ends_s = self.run(values, s)
            r_s = self.residuals(theta_s, ends_s, s)
        return s if changed else None

    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the shared parameters in step units."""
        return (np.array([_to_u(p, p.lower) for p in self.free]),
                np.array([_to_u(p, p.upper) for p in self.free]))

    def _jacobian(self, u, s, r, theta, ends, hs, motion=None) -> _Jacobian:
        """Forward-difference Jacobian in step units (a data row sees the shared parameters
        and its own segment's state: :class:`_Jacobian`).  The shared columns difference
        ``residuals`` itself; a data row's state columns come from the change of the model
        alone, times the robust loss's slope there when the problem is robust.

        ``motion``, the model's motion at (u, s) (``_integrate``), spares the run of every
        column whose parameter leaves the integrator's model as it is (a sensor's zero,
        cubic term or lag): the same motion is read with the moved value, which gives the
        very numbers a run would."""
        g = len(self.free)
        n_seg = self.segments.count
        rows_data = int(np.count_nonzero(self.fitted))
        n_links = self.links.size

        _lower, upper = self._bounds()
        packed = self.packed_of(self.values_of(u)) if motion is not None else None

        def direction(i: int) -> float:
            return 1.0 if u[i] + 1.0 <= upper[i] else -1.0  # stay inside the bounds

        def shared_column(i: int) -> np.ndarray:
            h = direction(i)
            du = u.copy()
            du[i] += h
            values = self.values_of(du)
            if packed is not None and all(
                    np.array_equal(a, b, equal_nan=True)
                    for a, b in zip(self.packed_of(values), packed, strict=True)):
                th, en = self.read(values, *motion)
            else:
                th, en = self.run(values, s, split=False)
            return (self.residuals(th, en, s) - r) / h

        def part_columns(indices: list[int]) -> list[tuple[int, np.ndarray]]:
            """Columns of parameters of different parts, from one run with all moved."""
            du = u.copy()
            h = np.array([direction(i) for i in indices])
            du[indices] += h
            th, en = self.run(self.values_of(du), s, split=False)
            change = self.residuals(th, en, s) - r
            return [(i, np.where(self.row_part == self.free[i].part, change / hi, 0.0))
                    for i, hi in zip(indices, h, strict=True)]

        def state_run(k: int) -> tuple[np.ndarray, np.ndarray]:
            ds = s.copy()
            ds[:, k] += hs[k]
            return self.run(self.values_of(u), ds, split=False)

        pool = _pool(self.threads, "shooting-jacobian")
        everywhere = [i for i, p in enumerate(self.free) if p.part is None]
        shared = [np.zeros(0)] * g
        for i, column in zip(everywhere, pool.map(shared_column, everywhere), strict=True):
            shared[i] = column
        for columns in pool.map(part_columns, _part_rounds(self.free)):
            for i, column in columns:
                shared[i] = column
        perturbed = list(pool.map(state_run, range(2)))
        # data rows: d(residual)/d(own state), one column pair per segment
        slope = robust_slope(self._data_residuals(theta)) if self.robust else None
        data_state = np.empty((2, rows_data))
        for k in range(2):
            th, _ = perturbed[k]
            d = (th[self.fitted] - theta[self.fitted]) / self.sigma
            d = np.where(np.isfinite(d), d, 0.0)
            data_state[k] = d if slope is None else d * slope  # the chain rule
        # link rows: (end_k - start_k+1) / scale; d/d s_k from the perturbed ends, d/d s_k+1 = -I
        scale = np.array([self.sigma, self.sigma * self.rate_scale])
        link_state = np.empty((n_links, 2, 2))
        for k in range(2):  # which state component was perturbed
            _, en = perturbed[k]
            d_end = (en[self.links] - ends[self.links]) / scale  # (links, 2)
            link_state[:, :, k] = np.where(np.isfinite(d_end), d_end, 0.0)
        return _Jacobian(
            shared=np.column_stack(shared) if g else np.zeros((r.size, 0)),
            data_state=data_state, segment_of_row=self.segment_of[self.fitted],
            links=self.links, link_state=link_state, link_next=-hs / scale, n_seg=n_seg)

    def _result(self, u, s, r, theta, ends, hs, success, message, iterations) -> ShootingFit:
        values = self.values_of(u)
        n = self.t.size
        prediction = np.full(n, np.nan)
        prediction[self.sample_of] = theta
        true_angle = np.full(n, np.nan)
        rate = np.full(n, np.nan)
        true_angle[self.sample_of], rate[self.sample_of] = self.motion(values, s)
        fit_rows = np.zeros(n, dtype=bool)
        fit_rows[self.sample_of[self.fitted]] = True
        residual = np.where(fit_rows, prediction - self.y, np.nan)
        held = self.segments.forecast_mask(n) & self.valid
        forecast = np.where(held, prediction - self.y, np.nan)
        jumps = ends[self.links] - s[self.links + 1]
        estimates, correlation = self._estimates(u, s, r, theta, ends, hs, residual)
        return ShootingFit(
            values=values, states=s, estimates=estimates, prediction=prediction, rate=rate,
            true_angle=true_angle,
            residual=residual, forecast_residual=forecast, jumps=jumps,
            n_params=len(self.free) + 2 * self.segments.count, success=success,
            message=message, iterations=iterations, correlation=correlation,
        )

    def _estimates(self, u, s, r, theta, ends, hs, residual):
        """95 % intervals of the shared parameters: (J^T J)^-1 scaled by the residual
        variance and widened by the residual's correlation time (effective samples).

        Robust, the M-estimator's: H^-1 E[psi^2] / E[psi'] with H = J^T diag(psi') J (psi
        = rho' / 2, the jumps' psi the jump itself), never below what Gaussian noise gives
        (ROBUST_GAUSSIAN_SCALE, as 1 is least squares'), and the correlation time that of
        psi, which is what the fit sums."""
        g = len(self.free)
        if g == 0:
            return {}, None
        jac = self._jacobian(u, s, r, theta, ends, hs)
        if self.robust:
            raw = self._data_residuals(theta)
            spread = _spread(raw)
            jumps = r[raw.size:]
            # rows of J sqrt(psi'): the data rows of the robust Jacobian are J times
            # robust_slope, and psi' / robust_slope^2 = 2 / (s (1 + s))
            rows = np.concatenate([np.sqrt(2.0 / (spread * (1.0 + spread))),
                                   np.ones(jumps.size)])
            psi = np.concatenate([psi_of(raw), jumps])
            curvature = np.concatenate([spread ** -3.0, np.ones(jumps.size)])
            floor = ROBUST_GAUSSIAN_SCALE
            variance = float(psi @ psi) / float(np.sum(curvature)) * r.size
            influence = np.full(residual.size, np.nan)
            finite = np.isfinite(residual)
            influence[finite] = psi_of(residual[finite] / self.sigma)
            tau = correlation_time(influence)
        else:
            rows = None
            floor = 1.0
            variance = float(r @ r)
            tau = correlation_time(residual)
        a = jac.normal_matrix(rows)
        dof = max(r.size - a.shape[0], 1)
        s2 = max(variance / dof, floor)
        try:
            unit = np.zeros((a.shape[0], g))
            unit[:g, :g] = np.eye(g)
            cov = splu(a).solve(unit)[:g, :g] * s2 * tau
        except RuntimeError:  # singular: some parameter has no influence
            cov = np.full((g, g), np.nan)
        values = self.values_of(u)
        out = {}
        var = np.diag(cov)
        m = self.coordinates
        spread = np.einsum("ij,jk,ik->i", m, cov, m)  # the coordinates' variances
        for i, p in enumerate(self.free):
            value = values[p.name]
            half = Z95 * math.sqrt(spread[i]) if spread[i] >= 0 else math.nan
            if not math.isfinite(half) or (p.log and half > 50.0):
                out[p.name] = Estimate(value)
            elif p.log:
                out[p.name] = Estimate(value, (value * math.exp(-half), value * math.exp(half)))
            else:
                out[p.name] = Estimate(value, (value - half, value + half))
        with np.errstate(invalid="ignore", divide="ignore"):
            sd = np.sqrt(np.maximum(var, 0.0))
            correlation = cov / np.outer(sd, sd)
        return out, correlation


def thread_count(threads: int | None) -> int:
    """The threads a fit uses when given ``threads`` (None: the machine's cores, up to 4)."""
    return threads or min(4, os.cpu_count() or 1)


class _InCaller:
    """One thread's share of work done in the calling thread: fits run side by side with a
    thread each (``analysis.discrepancy.forced_models.SideBySide``) would otherwise queue
    behind one shared pool thread."""

    @staticmethod
    def map(fn: Callable, items: Iterable) -> Iterator:
        return map(fn, items)


_POOLS: dict[tuple[int, str], ThreadPoolExecutor] = {}


@functools.cache
def _pool(threads: int, role: str) -> ThreadPoolExecutor | _InCaller:
    """A thread pool kept for the process: a fit asks for hundreds of Jacobians, and starting
    threads for each costs more than the columns they share out.  Each role has its own, so
    that work one pool's thread hands out never waits behind that very thread."""
    blas_on_one_thread()
    if threads <= 1:
        return _InCaller()
    if (threads, role) not in _POOLS:
        _POOLS[threads, role] = ThreadPoolExecutor(max_workers=threads,
                                                   thread_name_prefix=role)
    return _POOLS[threads, role]


def _check_parts(segments: Segments, part_of_segment: np.ndarray, parts: int) -> None:
    """Every segment in a part, the parts in order, no link across them."""
    part = part_of_segment
    if part.shape != (segments.count,) or (part.size and (
            part[0] != 0 or part[-1] != parts - 1 or np.any(~np.isin(np.diff(part), (0, 1))))):
        raise ValueError(f"part_of_segment must number the {segments.count} segments' parts "
                         f"0..{parts - 1} in order")
    if segments.count > 1 and np.any(segments.linked[:-1] & (np.diff(part) != 0)):
        raise ValueError("a segment is linked to the next part's first one")


def _part_rounds(free: Sequence[FreeParameter]) -> list[list[int]]:
    """The indices of the part-specific parameters in rounds, at most one of each part in a
    round (their columns are differenced together)."""
    by_part: dict[int, list[int]] = {}
    for i, p in enumerate(free):
        if p.part is not None:
            by_part.setdefault(p.part, []).append(i)
    depth = max((len(v) for v in by_part.values()), default=0)
    return [[v[k] for v in by_part.values() if len(v) > k] for k in range(depth)]


def _groups(sizes: np.ndarray, count: int) -> list[tuple[int, int]]:
    """At most ``count`` runs of consecutive segments with about equal samples each."""
    if count <= 1 or sizes.size < 2 * count:
        return [(0, int(sizes.size))]
    cuts = np.searchsorted(np.cumsum(sizes), np.arange(1, count) * sizes.sum() / count)
    edges = np.unique(np.concatenate([[0], np.clip(cuts, 1, sizes.size - 1), [sizes.size]]))
    return [(int(a), int(b)) for a, b in pairwise(edges)]


def _to_u(p: FreeParameter, x: float) -> float:
    """A bound in step units (infinite bounds stay infinite)."""
    if not math.isfinite(x):
        return x
    if p.log:
        if x <= 0:
            return -math.inf
        return (math.log(x) - math.log(p.start)) / p.step
    return (x - p.start) / p.step
