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
    if phi.size < 50:
        raise ValueError(f"the 0-1 test needs at least 50 samples, got {phi.size}")
    if not np.all(np.isfinite(phi)):
        raise ValueError("samples contain NaN or infinite values")
    spread = float(np.std(phi))
    if spread == 0.0:
        # a constant observable is a fixed point of the map: regular
        c_values = np.zeros(0)
        return ZeroOneResult(0.0, c_values, c_values)
    # K is scale invariant; normalising keeps the subtraction below well conditioned
    phi = (phi - np.mean(phi)) / spread
    rng = np.random.default_rng(seed)
    c_values = rng.uniform(c_range[0], c_range[1], n_c)
    n_cut = int(n_cut or phi.size // 10)
    if n_cut < 5:
        raise ValueError("n_cut must be at least 5")
    K_per_c = _correlations(phi, c_values, n_cut)
    return ZeroOneResult(float(np.median(K_per_c)), K_per_c, c_values)


@numba.njit(cache=True)
def _correlations(phi, c_values, n_cut):
    N = phi.size
    length = N - n_cut
    mean_sq = np.mean(phi) ** 2
    lags = np.arange(1, n_cut + 1).astype(np.float64)
    out = np.empty(c_values.size)
    for ic in range(c_values.size):
        c = c_values[ic]
        p = np.empty(N)
        q = np.empty(N)
        sp, sq = 0.0, 0.0
        for j in range(N):
            sp += phi[j] * math.cos((j + 1) * c)
            sq += phi[j] * math.sin((j + 1) * c)
            p[j] = sp
            q[j] = sq
        D = np.empty(n_cut)
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
