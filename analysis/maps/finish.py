"""The last stage of a map: classify the finished file's attractors, store the summary
and draw the figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.maps.figures import draw_map
from analysis.maps.store import read_map, write_summary
from analysis.maps.summary import Runner, summarize


def finish_map(
    path: str | Path,
    figure_path: str | Path,
    run: Runner | None = None,
    overlay: Any = None,
    workers: int = 1,
) -> dict:
    """Summarize a map file whose tasks are all done (chunks classified by ``run`` on its
    ``workers``), store the summary and draw the figure (with a recorded sweep's points,
    ``overlay``); returns the file's contents."""
    data = read_map(path)
    left = int(np.count_nonzero(data["tasks"]["done"] == 0))
    if left:
        raise ValueError(f"{path}: {left} tasks are not done yet")
    arrays, info = summarize(
        data["kind"], data["trajectories"], data["points"]["packed"].shape[0], run, workers
    )
    data.update(summary=arrays, summary_info=write_summary(path, arrays, info), complete=True)
    draw_map(data, figure_path, overlay)
    return data
