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
    per_bin = n // columns
    used = per_bin * columns
    # the tail that does not fill a whole bin is kept as it is (at most per_bin - 1 points)
    blocks = y[:used].reshape(columns, per_bin)
    low = np.argmin(blocks, axis=1)
    high = np.argmax(blocks, axis=1)
    first = np.minimum(low, high)
    second = np.maximum(low, high)
    base = np.arange(columns) * per_bin
    order = np.empty(2 * columns, dtype=np.int64)
    order[0::2] = base + first
    order[1::2] = base + second
    tail = np.arange(used, n)
    if tail.size:
        order = np.concatenate([order, [tail[np.argmin(y[tail])], tail[np.argmax(y[tail])]]])
        order[-2:] = np.sort(order[-2:])
    return x[order], y[order]
