"""The figure of a sweep explained: each model's bifurcation diagram over the measured one."""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from analysis.dynamics.continuation import ContinuationResult
from analysis.figure_style import legend_beside, save_figure
from analysis.sweep.diagram import DiagramComparison, JudgedStep
from analysis.sweep.steps import DOWN

MODEL_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple")
# Points of the way down are drawn this fraction of the step spacing to the right of the
# way up's, so that hysteresis shows as two columns.
DOWN_SHIFT = 0.15
# A model's points sit this fraction of the step spacing beside the measured ones.
MODEL_SHIFT = 0.06


def draw_diagrams(comparisons: Sequence[DiagramComparison], measured: Sequence[JudgedStep],
                  path: str | Path, *, title: str = "",
                  orbits: ContinuationResult | None = None, orbits_of: str = "") -> Path:
    """Each model's stroboscopic points (the angle at drive phase 0 of each settled
    period) over the measured ones, step by step, the way up and the way down side by
    side; the models' one-line summaries under the title; under them, when given, the
    periodic orbits of model ``orbits_of`` (:func:`analysis.sweep.diagram.model_orbits`),
    stable solid and unstable dashed.  Writes a PNG; returns its path.
    """
    if not comparisons:
        raise ValueError("no model to draw: give at least one comparison")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9.0, 5.0), dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots()
    steps = comparisons[0].steps
    settings = sorted({s.setting for s in steps})
    spacing = min((b - a for a, b in pairwise(settings)), default=1.0)

    def where(step_index: int) -> float:
        step = steps[step_index]
        return step.setting + (DOWN_SHIFT * spacing if step.direction == DOWN else 0.0)

    if orbits is not None:
        _draw_orbits(axes, orbits, orbits_of)
    for index, judged in enumerate(measured):
        if judged.cloud.size:
            axes.plot([where(index)] * judged.cloud.shape[0], judged.cloud[:, 0], ".",
                      color="black", markersize=3, label="measured" if index == 0 else None)
    for number, comparison in enumerate(comparisons):
        colour = MODEL_COLOURS[number % len(MODEL_COLOURS)]
        shift = MODEL_SHIFT * spacing * (number + 1)
        labelled = False
        for index, judged in enumerate(comparison.judged):
            if not judged.cloud.size:
                continue
            axes.plot([where(index) + shift] * judged.cloud.shape[0], judged.cloud[:, 0], "x",
                      color=colour, markersize=3,
                      label=None if labelled else comparison.name)
            labelled = True
        for index, step in enumerate(comparison.steps):
            if not step.agrees:  # a step whose regime disagrees is marked at the top
                axes.plot(where(index) + shift, 1.0, "v", color=colour, markersize=6,
                          transform=axes.get_xaxis_transform(), clip_on=False)
    axes.set_xlabel(comparisons[0].setting_name + "  (way down shifted right)")
    axes.set_ylabel("angle at drive phase 0 [rad]")
    lines = [title] if title else []
    lines += [c.summary() for c in comparisons]
    axes.set_title("\n".join(lines), fontsize=8, loc="left")
    legend_beside(axes, fontsize=8)
    return save_figure(figure, path)


def _draw_orbits(axes: Any, orbits: ContinuationResult, name: str) -> None:
    stable_label = f"{name} orbits, stable".strip()
    unstable_label = f"{name} orbits, unstable".strip()
    for branch in orbits.branches:
        if not branch.points:
            continue
        values = branch.values
        stable = branch.stable
        thetas = np.array([p.section_theta for p in branch.points])
        for column in range(thetas.shape[1]):
            theta = thetas[:, column]
            axes.plot(values, np.where(stable, theta, np.nan), "-", color="0.6", linewidth=1.0,
                      label=stable_label, zorder=0)
            axes.plot(values, np.where(stable, np.nan, theta), "--", color="0.75",
                      linewidth=1.0, label=unstable_label, zorder=0)
            stable_label = unstable_label = None
