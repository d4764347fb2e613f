"""Bifurcation diagrams over the drive amplitude ratio beta = A / L (or any model parameter):
simulated and recorded.

Simulated sweeps come in two kinds (``mode``):

* ``"continuation"`` (default) mimics the experiment: the up sweep starts each beta
  from the final state of the previous one, the down sweep likewise from the top, so
  hysteresis and coexisting attractors show as differences between the two.  Each
  direction is sequential; the two directions advance in lockstep, one two-member
  ensemble call per beta, so they run on two cores.
* ``"fixed"``: every beta starts from the same initial state; all runs are
  independent and spread over all cores.  Cheaper per core, but it shows whichever
  attractor that one initial state falls into.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis import quantities as q
from analysis.dynamics.model_parameters import model_with
from analysis.dynamics.poincare import PoincareSection
from analysis.dynamics.sweeps import PoincareSettings, continue_along, run_poincare
from analysis.figure_style import legend_beside, save_figure
from analysis.model import Model
from analysis.progress import ProgressCounts

if TYPE_CHECKING:  # matplotlib is imported by the plot functions only (slow import)
    from matplotlib.figure import Figure

DIRECTIONS = ("up", "down", "fixed", "recorded", "recorded up", "recorded down")


@dataclass(frozen=True)
class BifurcationDiagram:
    """Poincare angles per parameter step of one sweep.

    ``theta`` and ``theta_dot`` are (steps, samples) arrays (NaN where a step has fewer
    samples or its run stopped); ``direction`` is one of ``DIRECTIONS``: 'up', 'down',
    'fixed' (simulated), 'recorded', or 'recorded up' / 'recorded down' (a recorded sweep
    split by the way it went)
    """

    parameter: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    direction: str
    parameter_name: str = q.beta

    def scatter(self) -> tuple[np.ndarray, np.ndarray]:
        """(parameter, theta) pairs of every finite sample, ready for a scatter plot."""
        repeated = np.broadcast_to(self.parameter[:, None], self.theta.shape)
        finite = np.isfinite(self.theta)
        return repeated[finite], self.theta[finite]


def simulate_bifurcation(
    model: Model,
    beta_values: Sequence[float] | np.ndarray,
    *,
    periods: int = 500,
    record_periods: int = 100,
    mode: str = "continuation",
    initial_state: tuple[float, float] = (0.0, 0.0),
    rtol: float = 1e-8,
    atol: float = 1e-10,
    workers: int | None = None,
    progress: ProgressCounts | None = None,
    parameter: str = q.beta,
) -> tuple[BifurcationDiagram, ...]:
    """Bifurcation diagram(s) of ``model`` over ``beta_values`` (sorted ascending here), or
    over the values of another model ``parameter`` (a name :func:`model_with` knows).

    Each beta runs ``periods`` drive periods, of which the last ``record_periods`` give
    the Poincare samples (drive phase 0).  Returns (up, down) diagrams for
    ``mode="continuation"`` and a single 'fixed' diagram for ``mode="fixed"``.
    ``progress`` is told the runs done of all (a :class:`~analysis.progress.Progress`) as
    runs finish.
    """
    betas = np.sort(np.asarray(beta_values, dtype=float).ravel())
    if betas.size == 0:
        raise ValueError("beta_values is empty")
    if not 1 <= record_periods <= periods:
        raise ValueError(f"need 1 <= record_periods ({record_periods}) <= periods ({periods})")
    packed = np.array([model_with(model, parameter, value).pack() for value in betas])
    transient = periods - record_periods
    settings = PoincareSettings(transient, record_periods, rtol, atol)
    if mode == "fixed":
        initial = np.tile(np.asarray(initial_state, dtype=float), (betas.size, 1))
        runs = run_poincare(packed, initial, settings, workers=workers, progress=progress)
        return (BifurcationDiagram(betas, runs.theta, runs.theta_dot, "fixed", parameter),)
    if mode != "continuation":
        raise ValueError(f"mode = {mode!r}: choose 'continuation' or 'fixed'")
    # up and down advance in lockstep: one two-member ensemble call per step, in parallel
    up, down = continue_along(
        np.stack([packed, packed[::-1]]),
        initial_state,
        settings,
        workers=workers,
        progress=progress,
    )
    runs = {"up": up, "down": down}
    orders = {"up": np.arange(betas.size), "down": np.arange(betas.size)[::-1]}
    diagrams = []
    for name, order in orders.items():
        back = np.argsort(order)  # results back in ascending beta
        diagrams.append(
            BifurcationDiagram(betas, runs[name].theta[back], runs[name].theta_dot[back], name,
                               parameter)
        )
    return tuple(diagrams)


def bifurcation_from_recording(
    parameter_values: Sequence[float] | np.ndarray,
    sections: Sequence[PoincareSection | np.ndarray],
    *,
    parameter_name: str = q.beta,
    last: int | None = None,
) -> BifurcationDiagram:
    """Diagram of a recorded sweep: one Poincare section (or array of angles) per step.

    ``last`` keeps only the final samples of each step (the settled part after the
    step change).
    """
    if last is not None and last < 1:
        raise ValueError(f"last = {last!r}: keep at least 1 sample per step (None keeps all)")
    values = np.asarray(parameter_values, dtype=float).ravel()
    if values.size != len(sections):
        raise ValueError(
            f"{values.size} parameter values but {len(sections)} Poincare sections: "
            "need one section per sweep step"
        )
    thetas, rates = [], []
    for section in sections:
        if isinstance(section, PoincareSection):
            theta, rate = section.theta, section.theta_dot
        else:
            theta = np.asarray(section, dtype=float).ravel()
            rate = np.full(theta.size, np.nan)
        if last is not None:
            theta, rate = theta[-last:], rate[-last:]
        thetas.append(theta)
        rates.append(rate)
    width = max((t.size for t in thetas), default=0)
    theta_grid = np.full((values.size, width), np.nan)
    rate_grid = np.full((values.size, width), np.nan)
    for i, (theta, rate) in enumerate(zip(thetas, rates, strict=True)):
        theta_grid[i, : theta.size] = theta
        rate_grid[i, : rate.size] = rate
    return BifurcationDiagram(values, theta_grid, rate_grid, "recorded", parameter_name)


_STYLE = {
    "up": dict(color="tab:blue", label="simulation, sweep up"),
    "down": dict(color="tab:orange", label="simulation, sweep down"),
    "fixed": dict(color="tab:green", label="simulation, fixed initial state"),
    "recorded": dict(color="black", label="measured"),
    "recorded up": dict(color="black", label="measured, sweep up"),
    "recorded down": dict(color="tab:gray", label="measured, sweep down"),
}
# the down sweep drawn larger, so where the two sweeps agree both stay visible
_SIZE = {"recorded": 6.0, "recorded up": 6.0, "recorded down": 9.0, "down": 2.0}


def diagram_style(direction: str) -> dict[str, object]:
    """Colour, legend label and marker size (points^2) a diagram of ``direction`` is drawn with."""
    style = _STYLE.get(direction, dict(color="gray", label=direction))
    return {**style, "s": _SIZE.get(direction, 0.8)}



def plot_bifurcation(
    *diagrams: BifurcationDiagram,
    title: str | None = None,
    path: str | Path | None = None,
) -> Figure:
    """Draw diagrams on one axis (Agg, no window); saved as PNG when ``path`` is given."""
    if not diagrams:
        raise ValueError("nothing to plot: pass at least one BifurcationDiagram")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8.0, 5.0), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for diagram in diagrams:
        x, y = diagram.scatter()
        axes.scatter(x, y, marker=".", linewidths=0, alpha=0.8, **diagram_style(diagram.direction))
    axes.set_xlabel(diagrams[0].parameter_name)
    axes.set_ylabel("theta at drive phase 0 [rad]")
    if title:
        axes.set_title(title)
    legend = legend_beside(axes, markerscale=8)
    for handle in legend.legend_handles:
        handle.set_alpha(1.0)
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path)
    return figure
