"""Confidence intervals of least-squares estimates that stay honest when residuals are correlated.

The textbook covariance s^2 (J^T J)^-1 assumes white residuals.  Densely sampled
records are rarely white: sensor filtering, quantisation and above all model
misfit make neighbouring residuals alike, and the white formula then claims far
too much precision.  We use the heteroscedasticity-and-autocorrelation-consistent
sandwich (Newey-West, Bartlett weights) with a bandwidth taken from the measured
residual autocorrelation, never narrower than the white-noise interval.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Z95 = 1.959963984540054
CORRELATION_CUTOFF = 0.05  # the residual correlation time ends where rho first drops below this
BANDWIDTH_FACTOR = 2  # Bartlett weights need a window a few correlation times wide


@dataclass(frozen=True)
class Covariance:
    """Parameter covariance and what went into it."""

    matrix: np.ndarray
    white_matrix: np.ndarray
    variance_inflation: float  # largest ratio of sandwich to white variance over the parameters
    lag1_correlation: float
    residual_std: float

    def ci95(self, value: float, index: int) -> tuple[float, float]:
        """Symmetric 95 % interval of parameter ``index`` around ``value``."""
        half = Z95 * math.sqrt(max(self.matrix[index, index], 0.0))
        return (value - half, value + half)

    def derived_ci95(self, value: float, gradient: np.ndarray) -> tuple[float, float]:
        """95 % interval of a derived quantity with the given gradient (delta method)."""
        var = float(gradient @ self.matrix @ gradient)
        half = Z95 * math.sqrt(max(var, 0.0))
        return (value - half, value + half)


def autocorrelation(residual: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation rho_0..rho_max_lag of a residual sequence (rho_0 = 1)."""
    r = residual - residual.mean()
    n = r.size
    size = 1 << math.ceil(math.log2(2 * n))
    spectrum = np.fft.rfft(r, size)
    acov = np.fft.irfft(spectrum * np.conj(spectrum), size)[: max_lag + 1]
    return acov / acov[0] if acov[0] > 0 else np.zeros(max_lag + 1)


def correlation_time(residual: np.ndarray) -> float:
    """Integrated autocorrelation time (samples) of a residual: 1 for white noise."""
    r = residual[np.isfinite(residual)]
    if r.size < 8:
        return 1.0
    rho = autocorrelation(r, max(1, min(r.size // 4, 2000)))
    below = np.flatnonzero(rho[1:] < CORRELATION_CUTOFF)
    stop = int(below[0]) + 1 if below.size else rho.size
    return float(max(1.0, 1.0 + 2.0 * np.sum(rho[1:stop])))


def bandwidth(residual: np.ndarray) -> int:
    """Newey-West bandwidth: a few times the lag where the autocorrelation first fades."""
    n = residual.size
    max_lag = max(1, n // 4)
    rho = autocorrelation(residual, max_lag)
    below = np.flatnonzero(rho[1:] < CORRELATION_CUTOFF)
    fade = int(below[0]) + 1 if below.size else max_lag
    return int(min(max_lag, BANDWIDTH_FACTOR * fade))


def _long_run_outer(u: np.ndarray, lags: int) -> np.ndarray:
    """Sum over |k| <= lags of Bartlett-weighted sum_i u_i u_{i+k}^T (u is n x p)."""
    n, p = u.shape
    size = 1 << math.ceil(math.log2(2 * n))
    spectra = np.fft.rfft(u, size, axis=0)
    weights = 1.0 - np.arange(lags + 1) / (lags + 1.0)
    meat = np.zeros((p, p))
    for a in range(p):
        for b in range(a, p):
            cross = np.fft.irfft(np.conj(spectra[:, a]) * spectra[:, b], size)
            # cross[k] = sum_i u_a[i] u_b[i+k]; cross[-k] = sum_i u_a[i+k] u_b[i]
            forward = cross[: lags + 1]
            backward = np.concatenate(([cross[0]], cross[size - lags :][::-1]))
            value = float(weights @ forward + weights[1:] @ backward[1:])
            meat[a, b] = meat[b, a] = value
    return meat


def sandwich_covariance(
    blocks: Sequence[tuple[np.ndarray, np.ndarray]], n_params: int | None = None
) -> Covariance:
    """Covariance of least-squares parameters from (residual, Jacobian) blocks of separate records.

    Each block is one record's residual vector (n,) and Jacobian (n, p) at the
    solution; correlation is allowed within a block, none between blocks.
    """
    p = n_params if n_params is not None else blocks[0][1].shape[1]
    hessian = np.zeros((p, p))
    meat = np.zeros((p, p))
    sum_sq = 0.0
    count = 0
    lag1 = []
    for residual, jac in blocks:
        hessian += jac.T @ jac
        sum_sq += float(residual @ residual)
        count += residual.size
        lags = bandwidth(residual)
        meat += _long_run_outer(residual[:, None] * jac, lags)
        lag1.append(float(autocorrelation(residual, 1)[1]) if residual.size > 2 else 0.0)
    dof = max(count - p, 1)
    hessian_inv = np.linalg.pinv(hessian)
    white = sum_sq / dof * hessian_inv
    sandwich = count / dof * hessian_inv @ meat @ hessian_inv
    white_var = np.maximum(np.diag(white), 1e-300)
    sandwich_var = np.maximum(np.diag(sandwich), 0.0)
    ratio = sandwich_var / white_var
    # Keep the sandwich's correlation structure but never report less spread than white noise.
    scale = np.sqrt(np.maximum(sandwich_var, white_var))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = sandwich / np.sqrt(np.outer(sandwich_var, sandwich_var))
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    matrix = corr * np.outer(scale, scale)
    return Covariance(
        matrix=matrix,
        white_matrix=white,
        variance_inflation=float(max(1.0, ratio.max())),
        lag1_correlation=float(np.mean(lag1)) if lag1 else 0.0,
        residual_std=math.sqrt(sum_sq / dof),
    )
