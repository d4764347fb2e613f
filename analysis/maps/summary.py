"""What a finished map shows: which attractor each trajectory settled on, and per point how
many attractors coexist and which regime dominates.

Trajectories are grouped (per point for bifurcation and regime maps, all together for a
basin map, whose trajectories share one model) and each group's settled Poincare orbits
are matched into attractors by :func:`analysis.dynamics.basins.identify_attractors`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.dynamics.basins import NO_ATTRACTOR, identify_attractors
from analysis.dynamics.regime import KINDS

NO_REGIME = -1  # kind code where no trajectory of a point stayed in the model


def summarize(kind: str, trajectories: dict[str, np.ndarray], points: int) -> tuple[
    dict[str, np.ndarray], dict[str, Any]
]:
    """Summary arrays and plain facts of a complete map.

    Per trajectory: ``label`` (attractor within its group, -1 none), ``regime`` (index into
    analysis.dynamics.regime.KINDS, -1 none) and ``period`` (0 unless periodic).  Per
    point: ``attractors`` (how many coexist), the dominant attractor's ``point_regime``
    and ``point_period``, and its ``impacts_per_period``.  The facts name the attractors.
    """
    theta, theta_dot = trajectories["theta"], trajectories["theta_dot"]
    status, point = trajectories["status"], trajectories["point"]
    record_periods = theta.shape[1]
    label = np.full(point.size, NO_ATTRACTOR, dtype=np.int64)
    regime = np.full(point.size, NO_REGIME, dtype=np.int8)
    period = np.zeros(point.size, dtype=np.int16)
    count = np.zeros(points, dtype=np.int16)
    point_regime = np.full(points, NO_REGIME, dtype=np.int8)
    point_period = np.zeros(points, dtype=np.int16)
    impacts = np.full(points, np.nan)
    groups = [np.arange(point.size)] if kind == "basins" else _by_point(point, points)
    named: list[dict[str, Any]] = []
    for members in groups:
        if members.size == 0:
            continue
        labels, attractors = identify_attractors(
            theta[members], theta_dot[members], ok=status[members] == 0
        )
        label[members] = labels
        codes = np.array([KINDS.index(a.regime.kind) for a in attractors] + [NO_REGIME])
        periods = np.array([a.regime.period or 0 for a in attractors] + [0])
        regime[members] = codes[labels]  # label -1 picks the appended "none"
        period[members] = periods[labels]
        where = point[members[0]]
        count[where] = len(attractors)
        if attractors:
            dominant = int(np.argmax(np.bincount(labels[labels >= 0])))
            point_regime[where] = codes[dominant]
            point_period[where] = periods[dominant]
            impacts[where] = np.mean(trajectories["contacts"][members[labels == dominant]])
            impacts[where] /= record_periods
        if kind == "basins":
            named = [
                {
                    "name": a.name,
                    "regime": a.regime.kind,
                    "period": a.regime.period,
                    "fraction": a.basin_fraction,
                    "points": a.points.tolist(),
                }
                for a in attractors
            ]
    arrays = {
        "label": label,
        "regime": regime,
        "period": period,
        "attractors": count,
        "point_regime": point_regime,
        "point_period": point_period,
        "impacts_per_period": impacts,
    }
    info: dict[str, Any] = {"regime_names": list(KINDS), "no_regime": NO_REGIME}
    if kind == "basins":
        info["attractors"] = named
    info["coexisting_max"] = int(count.max()) if count.size else 0
    return arrays, info


def _by_point(point: np.ndarray, points: int) -> list[np.ndarray]:
    order = np.argsort(point, kind="stable")
    bounds = np.searchsorted(point[order], np.arange(points + 1))
    return [order[bounds[k] : bounds[k + 1]] for k in range(points)]


def finish_map(path: str | Path, figure_path: str | Path) -> dict[str, Any]:
    """Summarize a map file whose tasks are all done, store the summary and draw the figure;
    returns the file's contents."""
    from analysis.maps.figures import draw_map
    from analysis.maps.store import read_map, write_summary

    data = read_map(path)
    if not data["tasks"]["done"].all():
        raise ValueError(f"{path}: {np.count_nonzero(~data['tasks']['done'].astype(bool))} "
                         "tasks are not done yet")
    arrays, info = summarize(data["kind"], data["trajectories"], data["points"]["packed"].shape[0])
    write_summary(path, arrays, info)
    data = read_map(path)
    draw_map(data, figure_path)
    return data
