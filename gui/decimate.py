"""Min/max decimation for drawing long traces: two points per pixel column keep every peak.

A screen shows a few thousand columns; a 60 s trace at 40 kHz has 2.4 million samples.
Drawing the minimum and maximum of each column's samples draws the same picture
(the envelope, every spike) at a thousand times less cost than plotting them all.
"""

from __future__ import annotations

import numpy as np


def min_max_decimate(x: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` reduced to the min and max of ``y`` in each of ``columns`` equal bins.

    Returns the input unchanged when it already has no more than ``2 * columns``
    points.  Within each bin the min and max keep their time order, so a line through
    them looks like the full trace.  ``x`` must be increasing.
    """
    x = np.asarray(x)
    y = np.asarray(y)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"x and y must be 1-D of equal length, got {x.shape} and {y.shape}")
    if columns < 1:
        raise ValueError(f"columns = {columns}: need at least one pixel column")
    n = y.size
    if n <= 2 * columns:
        return x, y
    per_bin = -(-n // columns)  # ceil: the last bin may be short, never a long undrawn tail
    bins = -(-n // per_bin)
    padded = np.empty(bins * per_bin, dtype=y.dtype)
    padded[:n] = y
    padded[n:] = y[-1]  # repeats of the last sample: its index is clipped back below
    blocks = padded.reshape(bins, per_bin)
    low = np.argmin(blocks, axis=1)
    high = np.argmax(blocks, axis=1)
    base = np.arange(bins) * per_bin
    order = np.empty(2 * bins, dtype=np.int64)
    order[0::2] = base + np.minimum(low, high)
    order[1::2] = base + np.maximum(low, high)
    np.minimum(order, n - 1, out=order)
    return x[order], y[order]
