"""The 0-1 test for chaos (Gottwald and Melbourne 2004, 2009), correlation method.

Input is a scalar observable sampled once per drive period (a Poincare coordinate):
oversampled flow data make the test read periodic motion as chaotic, so sample at
the drive period.  K -> 0 for regular (periodic or quasi-periodic) motion, K -> 1 for
chaos.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

MIN_SAMPLES = 50  # the fewest samples the test is run on


@dataclass(frozen=True)
class ZeroOneResult:
    """K = median over the random frequencies c of the per-c correlation K_c."""

    K: float
    K_per_c: np.ndarray
    c_values: np.ndarray


def zero_one_test(
    samples: np.ndarray,
    *,
    n_c: int = 100,
    seed: int = 0,
    c_range: tuple[float, float] = (math.pi / 5.0, 4.0 * math.pi / 5.0),
    n_cut: int | None = None,
) -> ZeroOneResult:
    """K of the 0-1 test for a once-per-period series (at least ~100 samples, better 1000+).

    For each c drawn (seeded) from ``c_range`` — away from 0 and pi, where resonances
    spoil the test — the translation variables p_c, q_c are built, their mean square
    displacement M_c(n) (n <= n_cut = N/10) has its oscillatory term removed, and K_c
    is its correlation with n.
    """
    phi = np.asarray(samples, dtype=float).ravel()
    K_per_c, c_values = _per_c(phi[None], n_c, seed, c_range, n_cut)
    if K_per_c.shape[1] == 0:
        # a constant observable is a fixed point of the map: regular
        return ZeroOneResult(0.0, K_per_c[0], K_per_c[0])
    return ZeroOneResult(float(np.median(K_per_c[0])), K_per_c[0], c_values)


def zero_one_k(
    series: np.ndarray,
    *,
    n_c: int = 100,
    seed: int = 0,
    c_range: tuple[float, float] = (math.pi / 5.0, 4.0 * math.pi / 5.0),
    n_cut: int | None = None,
) -> np.ndarray:
    """K of :func:`zero_one_test` for every row of ``series`` (m, N) in one call: row by
    row the same numbers, without the cost of m calls."""
    phi = np.atleast_2d(np.asarray(series, dtype=float))
    K = np.zeros(phi.shape[0])
    varied = np.std(phi, axis=1) != 0.0  # a constant row is a fixed point: K = 0
    if varied.any():
        K_per_c, _ = _per_c(phi[varied], n_c, seed, c_range, n_cut)
        K[varied] = np.median(K_per_c, axis=1)
    return K


def _per_c(phi, n_c, seed, c_range, n_cut):
    """K_c of each row of phi (m, N) and the c drawn; no c (an empty table) when the
    rows are constant."""
    if phi.shape[1] < MIN_SAMPLES:
        raise ValueError(
            f"the 0-1 test needs at least {MIN_SAMPLES} samples, got {phi.shape[1]}"
        )
    if not np.all(np.isfinite(phi)):
        raise ValueError("samples contain NaN or infinite values")
    spread = np.std(phi, axis=1)
    if np.all(spread == 0.0):
        return np.zeros((phi.shape[0], 0)), np.zeros(0)
    # K is scale invariant; normalising keeps the subtraction below well conditioned
    phi = (phi - np.mean(phi, axis=1)[:, None]) / spread[:, None]
    rng = np.random.default_rng(seed)
    c_values = rng.uniform(c_range[0], c_range[1], n_c)
    n_cut = int(n_cut or phi.shape[1] // 10)
    if n_cut < 5:
        raise ValueError("n_cut must be at least 5")
    return _correlation_rows(phi, c_values, n_cut), c_values


@numba.njit(cache=True)
def _correlation_rows(phi, c_values, n_cut):
    """K_c of every row of phi; the rotations cos((j + 1) c), sin((j + 1) c) are the same
    for every row, so they are computed once."""
    N = phi.shape[1]
    cos_jc = np.empty((c_values.size, N))
    sin_jc = np.empty((c_values.size, N))
    for ic in range(c_values.size):
        for j in range(N):
            cos_jc[ic, j] = math.cos((j + 1) * c_values[ic])
            sin_jc[ic, j] = math.sin((j + 1) * c_values[ic])
    out = np.empty((phi.shape[0], c_values.size))
    for row in range(phi.shape[0]):
        out[row] = _correlations(phi[row], c_values, n_cut, cos_jc, sin_jc)
    return out


@numba.njit(cache=True)
def _correlations(phi, c_values, n_cut, cos_jc, sin_jc):
    N = phi.size
    length = N - n_cut
    mean_sq = np.mean(phi) ** 2
    lags = np.arange(1, n_cut + 1).astype(np.float64)
    out = np.empty(c_values.size)
    p = np.empty(N)
    q = np.empty(N)
    D = np.empty(n_cut)
    for ic in range(c_values.size):
        c = c_values[ic]
        sp, sq = 0.0, 0.0
        for j in range(N):
            sp += phi[j] * cos_jc[ic, j]
            sq += phi[j] * sin_jc[ic, j]
            p[j] = sp
            q[j] = sq
        for n in range(1, n_cut + 1):
            acc = 0.0
            for j in range(length):
                dp = p[j + n] - p[j]
                dq = q[j + n] - q[j]
                acc += dp * dp + dq * dq
            D[n - 1] = acc / length - mean_sq * (1.0 - math.cos(n * c)) / (1.0 - math.cos(c))
        out[ic] = _pearson(lags, D)
    return out


@numba.njit(cache=True)
def _pearson(a, b):
    am = a - np.mean(a)
    bm = b - np.mean(b)
    denominator = math.sqrt(np.sum(am * am) * np.sum(bm * bm))
    if denominator == 0.0:
        return 0.0
    return np.sum(am * bm) / denominator
