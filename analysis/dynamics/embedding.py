"""Delay embedding of a record: delay from mutual information, dimension from false neighbours.

The delay is the first minimum of the time-delayed mutual information (Fraser and
Swinney); the dimension is the smallest one at which the false nearest neighbours of
Kennel, Brown and Abarbanel (1992) have (nearly) vanished.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DelayChoice:
    """Delay [samples] at the first minimum of the mutual information, with the curve itself."""

    delay: int
    lags: np.ndarray
    mutual_information_nats: np.ndarray


@dataclass(frozen=True)
class DimensionChoice:
    """Embedding dimension from false nearest neighbours, with the FNN fraction per dimension."""

    dimension: int
    dimensions: np.ndarray
    false_fraction: np.ndarray


def default_bins(n_samples: int) -> int:
    """Histogram bins for a mutual-information estimate from ``n_samples`` pairs.

    Enough samples per 2-D cell (about 20 on average over the occupied ~bins^2/4 cells)
    keeps the estimator's bias small; 8..64 bins.
    """
    return int(np.clip(np.sqrt(n_samples / 5.0), 8, 64))


def mutual_information(x: np.ndarray, max_lag: int, *, bins: int | None = None) -> np.ndarray:
    """I(x_t; x_{t+lag}) in nats for lag = 0..max_lag, from a 2-D histogram on equal-width bins."""
    x = _as_series(x)
    if max_lag < 1 or max_lag >= x.size // 2:
        raise ValueError(
            f"max_lag = {max_lag}: need 1 <= max_lag < {x.size // 2} (half the record)"
        )
    bins = bins or default_bins(x.size - max_lag)
    low, high = float(x.min()), float(x.max())
    if high <= low:
        raise ValueError("x is constant: mutual information is undefined")
    symbols = np.minimum(((x - low) / (high - low) * bins).astype(np.int64), bins - 1)
    out = np.empty(max_lag + 1)
    for lag in range(max_lag + 1):
        a = symbols[: x.size - lag]
        b = symbols[lag:]
        joint = np.bincount(a * bins + b, minlength=bins * bins).astype(float)
        joint /= joint.sum()
        pa = joint.reshape(bins, bins).sum(axis=1)
        pb = joint.reshape(bins, bins).sum(axis=0)
        outer = np.outer(pa, pb).ravel()
        used = joint > 0
        out[lag] = float(np.sum(joint[used] * np.log(joint[used] / outer[used])))
    return out


def first_minimum(values: np.ndarray, *, flat_fraction: float = 0.02) -> int | None:
    """Lag of the first clear minimum of a mutual-information curve, centred on its flat bottom.

    Histogram estimates wobble from lag to lag (the bin grid aliases against the
    data), and for nearly periodic signals the bottom is a broad plateau.  So the
    curve is median-filtered over 3 lags, the first minimum standing out by at least
    ``flat_fraction`` of the total drop is taken, and the answer is the middle of the
    stretch around it that stays within that same margin of it.
    """
    values = np.asarray(values, dtype=float)
    if values.size < 3:
        return None
    from scipy.ndimage import median_filter  # here: the map command needs no scipy.signal
    from scipy.signal import find_peaks

    smooth = median_filter(values, 3, mode="nearest")
    margin = flat_fraction * (smooth[0] - smooth.min())
    index, _ = find_peaks(-smooth, prominence=max(margin, 1e-12), plateau_size=(1, None))
    if index.size == 0:
        return None
    i = int(index[0])
    level = smooth[i] + margin
    left = right = i
    while left > 1 and smooth[left - 1] <= level:
        left -= 1
    while right < smooth.size - 1 and smooth[right + 1] <= level:
        right += 1
    return round(0.5 * (left + right))


def mutual_information_delay(
    x: np.ndarray, *, max_lag: int | None = None, bins: int | None = None
) -> DelayChoice:
    """Embedding delay [samples] at the first minimum of the mutual information.

    When the curve has no minimum within ``max_lag`` (default: a tenth of the record),
    the first lag where it drops below 1/e of its zero-lag value is used instead.
    """
    x = _as_series(x)
    max_lag = max_lag or max(2, x.size // 10)
    curve = mutual_information(x, max_lag, bins=bins)
    delay = first_minimum(curve)
    if delay is None:
        below = np.flatnonzero(curve < curve[0] / np.e)
        if below.size == 0:
            raise ValueError(
                f"mutual information has no minimum within max_lag = {max_lag} samples and never "
                "falls below 1/e of its start: pass a larger max_lag or decimate the record"
            )
        delay = int(below[0])
    return DelayChoice(max(1, int(delay)), np.arange(max_lag + 1), curve)


def delay_embed(x: np.ndarray, dimension: int, delay: int) -> np.ndarray:
    """Delay vectors (x_i, x_{i+delay}, ..., x_{i+(dimension-1) delay}) as rows."""
    x = _as_series(x)
    if dimension < 1 or delay < 1:
        raise ValueError(f"dimension = {dimension}, delay = {delay}: both must be >= 1")
    count = x.size - (dimension - 1) * delay
    if count < 2:
        raise ValueError(
            f"a record of {x.size} samples is too short for dimension {dimension} at delay {delay}"
        )
    return np.column_stack([x[k * delay : k * delay + count] for k in range(dimension)])


def false_nearest_neighbours(
    x: np.ndarray,
    delay: int,
    *,
    max_dimension: int = 8,
    distance_ratio: float = 15.0,
    attractor_ratio: float = 2.0,
    theiler_window: int = 0,
) -> np.ndarray:
    """Fraction of false nearest neighbours for dimensions 1..max_dimension (Kennel et al. 1992).

    A neighbour in dimension m is false when adding coordinate m+1 stretches the pair
    by more than ``distance_ratio`` times its distance (criterion 1) or makes their
    distance exceed ``attractor_ratio`` times the spread of the data (criterion 2).
    Neighbours closer in time than ``theiler_window`` samples are skipped.
    """
    x = _as_series(x)
    spread = float(np.std(x))
    fractions = np.empty(max_dimension)
    for m in range(1, max_dimension + 1):
        vectors = delay_embed(x, m + 1, delay)  # the last column is the (m+1)-th coordinate
        head, extra = vectors[:, :m], vectors[:, m]
        neighbour, distance = _nearest_neighbours(head, theiler_window, 1e-9 * spread)
        valid = neighbour >= 0
        stretch = np.abs(extra[valid] - extra[neighbour[valid]])
        d_m = distance[valid]
        with np.errstate(divide="ignore", invalid="ignore"):
            first = stretch > distance_ratio * d_m
        second = np.sqrt(d_m**2 + stretch**2) > attractor_ratio * spread
        fractions[m - 1] = float(np.mean(first | second)) if valid.any() else np.nan
    return fractions


def fnn_dimension(
    x: np.ndarray,
    delay: int,
    *,
    max_dimension: int = 8,
    threshold: float = 0.01,
    theiler_window: int = 0,
) -> DimensionChoice:
    """Smallest dimension whose false-neighbour fraction is below ``threshold``.

    With noise the fraction never reaches zero; then the dimension where it stops
    falling (its minimum) is taken.
    """
    fractions = false_nearest_neighbours(
        x, delay, max_dimension=max_dimension, theiler_window=theiler_window
    )
    dims = np.arange(1, max_dimension + 1)
    below = np.flatnonzero(fractions < threshold)
    dimension = int(dims[below[0]]) if below.size else int(dims[np.nanargmin(fractions)])
    return DimensionChoice(dimension, dims, fractions)


def _nearest_neighbours(
    points: np.ndarray, theiler_window: int, min_distance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each point's nearest neighbour (index, distance) at least ``theiler_window`` apart in time.

    Duplicates (closer than ``min_distance``, i.e. equal up to round-off, as in an
    exactly periodic record) are skipped: the ratio of criterion 1 is meaningless there.
    Points whose neighbour is not among the first candidates get -1.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    n = points.shape[0]
    k = min(n, 2 * theiler_window + 8)
    neighbour = np.full(n, -1, dtype=np.int64)
    distance = np.full(n, np.inf)
    pending = np.arange(n)
    while pending.size:
        dist, idx = tree.query(points[pending], k=k)
        dist = dist.reshape(pending.size, k)
        idx = idx.reshape(pending.size, k)
        ok = (np.abs(idx - pending[:, None]) > theiler_window) & (dist > min_distance) & (idx < n)
        has = ok.any(axis=1)
        first = np.argmax(ok, axis=1)
        rows = pending[has]
        neighbour[rows] = idx[has, first[has]]
        distance[rows] = dist[has, first[has]]
        pending = pending[~has]
        if k >= n:
            break
        k = min(n, 4 * k)
    return neighbour, distance


def _as_series(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"expected a 1-D series, got shape {x.shape}")
    if x.size < 16:
        raise ValueError(f"series of {x.size} samples is too short (need at least 16)")
    if not np.all(np.isfinite(x)):
        raise ValueError("series contains NaN or infinite samples; cut or fill the gaps first")
    return x
