"""What a finished map shows: which attractor each trajectory settled on, and per point how
many attractors coexist and which regime dominates.

Trajectories are grouped (per point for bifurcation and regime maps, all together for a
basin map, whose trajectories share one model) and each group's settled Poincare orbits
are matched into attractors by
:func:`analysis.dynamics.basins.identify_attractor_groups`.
Groups are classified in chunks of plain arrays, so the map's workers can share the work
(``run``); the result does not depend on who classified which chunk.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from analysis.dynamics.basins import NO_ATTRACTOR, identify_attractor_groups
from analysis.dynamics.regime import KINDS

NO_REGIME = -1  # kind code where no trajectory of a point stayed in the model
CHUNKS_PER_WORKER = 4  # chunks of groups classified per worker: few, as each is vectorised

Chunk = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # theta, theta_dot, ok, group ends
Runner = Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]]


def classify_chunk(chunk: Chunk) -> list[dict[str, Any]]:
    """Attractors of each group of a chunk (rows ``ends[k-1]:ends[k]``): per group the
    labels and, per attractor, its regime code, period, name and points."""
    theta, theta_dot, ok, ends = chunk
    return [
        {
            "labels": labels,
            "codes": [KINDS.index(a.regime.kind) for a in attractors],
            "periods": [a.regime.period or 0 for a in attractors],
            "names": [a.name for a in attractors],
            "fractions": [a.basin_fraction for a in attractors],
            "points": [a.points for a in attractors],
        }
        for labels, attractors in identify_attractor_groups(theta, theta_dot, ends, ok=ok)
    ]


def summarize(
    kind: str,
    trajectories: dict[str, np.ndarray],
    points: int,
    run: Runner | None = None,
    workers: int = 1,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Summary arrays and plain facts of a complete map; ``run(function, inputs)`` classifies
    the chunks, CHUNKS_PER_WORKER for each of its ``workers`` (default: here, one after
    another).

    Per trajectory: ``label`` (attractor within its group, -1 none), ``regime`` (index into
    analysis.dynamics.regime.KINDS, -1 none) and ``period`` (0 unless periodic).  Per
    point: ``attractors`` (how many coexist), the dominant attractor's ``point_regime``
    and ``point_period``, and its ``impacts_per_period``.  The facts name the attractors
    of a basin map.
    """
    theta, theta_dot = trajectories["theta"], trajectories["theta_dot"]
    status, point = trajectories["status"], trajectories["point"]
    groups = [np.arange(point.size)] if kind == "basins" else _by_point(point, points)
    per_chunk = max(1, math.ceil(len(groups) / (CHUNKS_PER_WORKER * workers)))
    chunks, members_of = [], []
    for start in range(0, len(groups), per_chunk):
        members = groups[start : start + per_chunk]
        rows = np.concatenate(members)
        ends = np.cumsum([m.size for m in members])
        chunks.append((theta[rows], theta_dot[rows], status[rows] == 0, ends))
        members_of.extend(members)
    results = [group for part in (run or _here)(classify_chunk, chunks) for group in part]

    label = np.full(point.size, NO_ATTRACTOR, dtype=np.int64)
    regime = np.full(point.size, NO_REGIME, dtype=np.int8)
    period = np.zeros(point.size, dtype=np.int16)
    count = np.zeros(points, dtype=np.int16)
    point_regime = np.full(points, NO_REGIME, dtype=np.int8)
    point_period = np.zeros(points, dtype=np.int16)
    impacts = np.full(points, np.nan)
    record_periods = theta.shape[1]
    for members, result in zip(members_of, results, strict=True):
        if members.size == 0:
            continue
        labels = result["labels"]
        codes = np.array([*result["codes"], NO_REGIME])  # label -1 picks the last: none
        periods = np.array([*result["periods"], 0])
        label[members] = labels
        regime[members] = codes[labels]
        period[members] = periods[labels]
        where = point[members[0]]
        count[where] = len(result["names"])
        if result["names"]:
            dominant = int(np.argmax(np.bincount(labels[labels >= 0])))
            point_regime[where] = codes[dominant]
            point_period[where] = periods[dominant]
            on_it = members[labels == dominant]
            impacts[where] = np.mean(trajectories["contacts"][on_it]) / record_periods
    arrays = {
        "label": label,
        "regime": regime,
        "period": period,
        "attractors": count,
        "point_regime": point_regime,
        "point_period": point_period,
        "impacts_per_period": impacts,
    }
    info: dict[str, Any] = {"regime_names": list(KINDS), "no_regime": NO_REGIME,
                            "coexisting_max": int(count.max()) if count.size else 0}
    if kind == "basins":
        (only,) = results
        info["attractors"] = [
            {"name": name, "regime": KINDS[code], "period": k or None, "fraction": fraction,
             "points": points.tolist()}
            for name, code, k, fraction, points in zip(
                only["names"], only["codes"], only["periods"], only["fractions"],
                only["points"], strict=True,
            )
        ]
    return arrays, info


def _here(function: Callable[[Any], Any], inputs: Sequence[Any]) -> list[Any]:
    return [function(item) for item in inputs]


def _by_point(point: np.ndarray, points: int) -> list[np.ndarray]:
    order = np.argsort(point, kind="stable")
    bounds = np.searchsorted(point[order], np.arange(points + 1))
    return [order[bounds[k] : bounds[k + 1]] for k in range(points)]
