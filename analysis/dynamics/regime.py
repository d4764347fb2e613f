"""Regime of forced motion (:class:`Regime`), and the classification of simulated orbits.

:func:`classify_regime` classifies noise-free Poincare samples (simulated orbits, basin
maps): recurrence within a tolerance relative to the attractor's size, then the 0-1
test K and, when given, the largest Lyapunov exponent.  The spectrum, when given,
names the sub- and superharmonics.  Measured records are judged, aware of their
noise, by :func:`analysis.dynamics.measured_regime.judge_regime`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from analysis.dynamics.chaos01 import MIN_SAMPLES, zero_one_test
from analysis.dynamics.poincare import PoincareSection
from analysis.dynamics.spectrum import Spectrum

KINDS = ("periodic", "quasi_periodic", "chaotic", "undetermined")


@dataclass(frozen=True)
class Regime:
    """What the motion is, and why we think so.

    ``kind`` is one of 'periodic', 'quasi_periodic', 'chaotic' or (a measured record
    whose tests disagree) 'undetermined'; ``period`` is the number of drive periods of a
    periodic response (None otherwise); ``evidence`` holds 'recurrence' (return distance
    per lag 1..n), 'K', the Lyapunov exponent, 'subharmonics', 'superharmonics',
    'incommensurate' when known, and what ``measured_regime.judge_regime`` adds; ``label``
    is for people.
    """

    kind: str
    period: int | None
    label: str
    evidence: MappingProxyType[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    @property
    def short_name(self) -> str:
        """'period-2', 'quasi-periodic', 'chaotic' or 'undetermined' (short names for maps)."""
        if self.kind == "periodic":
            return f"period-{self.period}"
        return self.kind.replace("_", "-")


def recurrence_distances(
    points: np.ndarray,
    max_period: int,
    *,
    scale: np.ndarray | float | None = None,
    quantile: float = 0.95,
) -> np.ndarray:
    """Return distance after n = 1..max_period iterations, relative to the attractor size.

    Coordinates are divided by ``scale`` (default: per coordinate, the larger of the
    points' peak-to-peak spread and their RMS, so a period-1 point is not judged by
    its own jitter); the distance is the Chebyshev norm, summarised by ``quantile``
    over the points so that a rare glitch in measured data does not hide a period.
    """
    points = _as_points(points)
    normalised = points / _scale(points, scale)
    return stacked_recurrence_distances(normalised[None], max_period, quantile=quantile)[0]


def stacked_recurrence_distances(
    orbits: np.ndarray, max_period: int, *, quantile: float = 0.95
) -> np.ndarray:
    """:func:`recurrence_distances` of many orbits at once: ``orbits`` is (m, n, d), each
    orbit already divided by its scale; returns (m, max_period), row by row the same
    numbers as one orbit at a time."""
    coordinates = np.moveaxis(np.asarray(orbits, dtype=float), 2, 0).copy()  # (d, m, n)
    count, length = coordinates.shape[1:]
    out = np.full((count, max_period), np.inf)
    for n in range(1, max_period + 1):
        if length <= n + 1:
            break
        d = np.abs(coordinates[0, :, n:] - coordinates[0, :, :-n])
        for coordinate in coordinates[1:]:  # the Chebyshev norm
            np.maximum(d, np.abs(coordinate[:, n:] - coordinate[:, :-n]), out=d)
        out[:, n - 1] = np.quantile(d, quantile, axis=1)
    return out


def classify_regime(
    poincare: PoincareSection | np.ndarray,
    *,
    spectrum: Spectrum | None = None,
    lyapunov_exponent: float | None = None,
    scale: np.ndarray | float | None = None,
    tolerance: float = 1e-3,
    noise_tolerance: float = 0.05,
    max_period: int = 16,
    chaos_threshold: float = 0.5,
    lyapunov_threshold: float = 0.0,
    seed: int = 0,
    recurrence: np.ndarray | None = None,
    K: float | None = None,
) -> Regime:
    """Classify post-transient Poincare samples (one per drive period; (n,) or (n, d) or a section).

    Periodic with period n: the smallest n whose recurrence distance is within
    ``tolerance`` of the attractor size, or, for noisy measured orbits, within
    ``noise_tolerance`` and a clear dip (5x below the median over the other lags);
    period 1 when every lag stays within ``noise_tolerance`` (a noisy fixed point).
    Otherwise chaotic when the 0-1 test's K exceeds ``chaos_threshold`` or the given
    Lyapunov exponent exceeds ``lyapunov_threshold``, else quasi-periodic.  (The
    0-1 test reads measurement noise as chaos, hence the noisy-period rule first.)
    ``recurrence`` (the points' :func:`recurrence_distances` at ``scale``, lags 1 to
    ``max_period`` or more) and ``K`` (the 0-1 test's K of the first coordinate with
    ``seed``, :func:`analysis.dynamics.chaos01.zero_one_k`): when the caller has them
    already, they are not computed again.
    """
    points = _as_points(poincare.points if isinstance(poincare, PoincareSection) else poincare)
    if points.shape[0] < 3:
        raise ValueError(f"need at least 3 Poincare samples to classify, got {points.shape[0]}")
    max_period = _lags(points.shape[0], max_period)
    if recurrence is None:
        recurrence = recurrence_distances(points, max_period, scale=scale)
    else:
        recurrence = np.array(recurrence[:max_period], dtype=float)
    evidence: dict[str, Any] = {"recurrence": recurrence, "tolerance": tolerance}
    if lyapunov_exponent is not None:
        evidence["lyapunov"] = float(lyapunov_exponent)
    harmonics = harmonic_content(spectrum)
    evidence.update(harmonics)
    period = _period(recurrence, tolerance, noise_tolerance)
    if period is not None:
        label = f"period-{period}" + harmonic_text(harmonics)
        return Regime("periodic", period, label, MappingProxyType(evidence))
    if points.shape[0] >= MIN_SAMPLES:
        K = zero_one_test(points[:, 0], seed=seed).K if K is None else float(K)
        evidence["K"] = K
    else:
        K = float("nan")
    lyapunov_says_chaos = lyapunov_exponent is not None and lyapunov_exponent > lyapunov_threshold
    if lyapunov_says_chaos or (np.isfinite(K) and chaos_threshold < K):
        details = [f"K = {K:.2f}"] if np.isfinite(K) else []
        if lyapunov_exponent is not None:
            details.append(f"lambda = {lyapunov_exponent:.3g}")
        return Regime(
            "chaotic", None, f"chaotic ({', '.join(details)})", MappingProxyType(evidence)
        )
    if not np.isfinite(K):
        raise ValueError(
            f"not periodic within the tolerance and too few samples (< {MIN_SAMPLES}) for the "
            "0-1 test: pass a Lyapunov exponent or more Poincare samples"
        )
    label = f"quasi-periodic (K = {K:.2f})"
    if harmonics.get("incommensurate"):
        label += f", lines at {', '.join(harmonics['incommensurate'])}"
    return Regime("quasi_periodic", None, label, MappingProxyType(evidence))


def closing_period(
    recurrence: np.ndarray,
    samples: int,
    *,
    tolerance: float = 1e-3,
    noise_tolerance: float = 0.05,
    max_period: int = 16,
) -> int | None:
    """The period :func:`classify_regime` finds in ``samples`` Poincare points whose
    recurrence distances (lags 1, 2, ...) are ``recurrence``; None when the orbit does not
    close (quasi-periodic or chaotic)."""
    lags = _lags(samples, max_period)
    return _period(np.asarray(recurrence[:lags], dtype=float), tolerance, noise_tolerance)


def _lags(samples: int, max_period: int) -> int:
    """The longest lag tried: a period must repeat at least twice in the samples."""
    return max(1, min(max_period, (samples - 2) // 2))


def _period(recurrence: np.ndarray, tolerance: float, noise_tolerance: float) -> int | None:
    """Smallest lag that closes the orbit: within tolerance, or a clear dip within the noise."""
    exact = np.flatnonzero(recurrence <= tolerance)
    if exact.size:
        return int(exact[0] + 1)
    finite = np.isfinite(recurrence)
    for n in np.flatnonzero(finite & (recurrence <= noise_tolerance)):
        others = np.delete(recurrence, n)
        others = others[np.isfinite(others)]
        if others.size >= 2 and 5.0 * recurrence[n] <= np.median(others):
            return int(n + 1)
    # A noisy fixed point has no dip: every lag returns to the same small cloud.
    if finite.any() and np.all(recurrence[finite] <= noise_tolerance):
        return 1
    return None


def harmonic_content(spectrum: Spectrum | None) -> dict[str, Any]:
    """Peak labels sorted into 'subharmonics', 'superharmonics' and 'incommensurate' lines,
    each by ascending frequency ({} without a spectrum or its drive frequency)."""
    if spectrum is None or spectrum.drive_frequency_hz is None:
        return {}
    sub, sup, incommensurate = [], [], []
    for peak in sorted(spectrum.peaks, key=lambda peak: peak.frequency_hz):
        if peak.harmonic is None:
            incommensurate.append(peak.label)
        elif peak.harmonic.denominator > 1:
            sub.append(peak.label)
        elif peak.harmonic > 1:
            sup.append(peak.label)
    return {"subharmonics": sub, "superharmonics": sup, "incommensurate": incommensurate}


def harmonic_text(harmonics: dict[str, Any], shown: int = 4) -> str:
    """' (subharmonics 1/2 f, 3/2 f; superharmonics 2 f, 3 f, ...)', or '' without a spectrum."""
    parts = []
    for kind in ("subharmonics", "superharmonics"):
        labels = harmonics.get(kind) or []
        if labels:
            more = ", ..." if len(labels) > shown else ""
            parts.append(f"{kind} {', '.join(labels[:shown])}{more}")
    return f" ({'; '.join(parts)})" if parts else ""


def _as_points(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim == 1:
        points = points[:, None]
    if points.ndim != 2 or points.shape[0] == 0:
        raise ValueError(f"Poincare samples must be (n,) or (n, d), got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("Poincare samples contain NaN or infinite values")
    return points


def _scale(points: np.ndarray, scale: np.ndarray | float | None) -> np.ndarray:
    if scale is None:
        spread = np.ptp(points, axis=0)
        rms = np.sqrt(np.mean(points**2, axis=0))
        size = np.maximum(spread, rms)
    else:
        size = np.broadcast_to(np.asarray(scale, dtype=float), (points.shape[1],)).copy()
    tiny = np.finfo(float).tiny
    return np.where(size > 0, size, tiny)
