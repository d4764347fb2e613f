"""The figure of a map file (PNG, Agg backend): the bifurcation diagram, the colour map of
regimes, or the basins of attraction, each with a legend of what the colours are."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.dynamics.basins import Attractor, BasinMap, plot_basins
from analysis.dynamics.regime import KINDS, Regime
from analysis.figure_style import legend_beside, save_figure
from analysis.maps.overlay import RecordedSweep
from analysis.maps.plan import ROLE_DOWN, ROLE_RANDOM, ROLE_UP
from analysis.maps.summary import NO_REGIME

_ROLE_STYLE = {
    ROLE_UP: dict(color="tab:blue", label="sweep up (continuation)", s=1.5),
    ROLE_DOWN: dict(color="tab:orange", label="sweep down (continuation)", s=3.0),
    ROLE_RANDOM: dict(color="tab:green", label="random initial states", s=0.8),
}
# tab20 without its browns, pinks and greys, which name the other regimes
_PERIOD_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#17becf", "#bcbd22",
                   "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#9edae5", "#dbdb8d"]
_FIXED_COLOURS = {"quasi-periodic": "#e377c2", "chaotic": "#8c564b",
                  "undetermined": "#7f7f7f", "left the model": "#d0d0d0"}
MAX_NAMED_PERIOD = len(_PERIOD_COLOURS) - 1  # one colour left for the longer periods


def draw_map(
    data: dict[str, Any], path: str | Path, overlay: RecordedSweep | None = None
) -> Path:
    """Draw the map read by :func:`analysis.maps.store.read_map` to ``path`` (PNG), a
    bifurcation map with a recorded sweep's points over it when ``overlay`` is given."""
    if data["kind"] == "basins":
        return save_figure(_basins(data), path)
    figure = _bifurcation(data, overlay) if data["kind"] == "bifurcation" else _regimes(data)
    return save_figure(figure, path, crop=False)  # constrained layout: drawn once


def _figure(size: tuple[float, float], rows: int = 1, heights: tuple[int, ...] = (1,)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, 1, sharex=True, gridspec_kw={"height_ratios": heights})
    return figure, axes


def _title(data: dict[str, Any]) -> str:
    settings = data["settings"]
    return (f"{data['kind']} map: {data['trajectories']['point'].size} trajectories, "
            f"{settings['transient_periods']} + {settings['record_periods']} periods each")


def _bifurcation(data: dict[str, Any], overlay: RecordedSweep | None):
    name = data["settings"]["axes"][0]["name"]
    values = data["points"][name]
    traj = data["trajectories"]
    figure, (top, bottom) = _figure((8.0, 6.0), 2, (3, 1))
    x = values[traj["point"]]
    for role, style in _ROLE_STYLE.items():
        rows = traj["role"] == role
        theta = traj["theta"][rows]
        finite = np.isfinite(theta)
        if not finite.any():
            continue
        xs = np.broadcast_to(x[rows][:, None], theta.shape)[finite]
        top.scatter(xs, theta[finite], marker=".", linewidths=0, alpha=0.8, **style)
    if overlay is not None:
        for direction, marker in (("up", "^"), ("down", "v")):
            steps = [k for k, d in enumerate(overlay.directions) if d == direction]
            xs = np.concatenate([np.full(overlay.theta[k].size, overlay.values[k]) for k in steps])
            ys = np.concatenate([overlay.theta[k] for k in steps])
            top.scatter(xs, ys, s=14, marker=marker, facecolors="none", edgecolors="black",
                        linewidths=0.6, label=f"recorded sweep, {direction}")
    top.set_ylabel("theta at drive phase 0 [rad]")
    top.set_title(_title(data))
    legend = legend_beside(top, fontsize="small")
    for handle in legend.legend_handles:  # the map's dots are tiny: legible marks instead
        handle.set_alpha(1.0)
        handle.set_sizes([30.0])
    bottom.step(values, data["summary"]["attractors"], where="mid", color="black")
    bottom.set_ylabel("attractors")
    bottom.set_xlabel(name)
    return figure


def _categories(regime: np.ndarray, period: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """An index per point into a list of category names ('period-2', 'chaotic', ...);
    periods above MAX_NAMED_PERIOD share one category, so every colour stays distinct."""
    names = []
    for code, k in zip(regime, period, strict=True):
        if code == NO_REGIME:
            names.append("left the model")
        elif KINDS[code] != "periodic":
            names.append(KINDS[code].replace("_", "-"))
        elif k > MAX_NAMED_PERIOD:
            names.append(f"period > {MAX_NAMED_PERIOD}")
        else:
            names.append(f"period-{k}")

    def order(name: str) -> tuple[int, int]:
        if name.startswith("period-"):
            return (0, int(name.split("-")[1]))
        return (1, [f"period > {MAX_NAMED_PERIOD}", *_FIXED_COLOURS].index(name))

    legend = sorted(set(names), key=order)
    return np.array([legend.index(name) for name in names]), legend


def _colours(legend: list[str]) -> list[str]:
    periodic = iter(_PERIOD_COLOURS)
    return [_FIXED_COLOURS.get(name) or next(periodic) for name in legend]


def _regimes(data: dict[str, Any]):
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    first, second = data["settings"]["axes"]
    summary = data["summary"]
    index, legend = _categories(summary["point_regime"], summary["point_period"])
    shape = (first["count"], second["count"])
    grid = index.reshape(shape).T  # rows: the second axis (y), columns: the first (x)
    colours = _colours(legend)
    figure, axes = _figure((8.0, 6.0))
    x, y = data["axes"][first["name"]], data["axes"][second["name"]]
    axes.imshow(
        grid, origin="lower", aspect="auto", interpolation="nearest",
        extent=_extent(x, y), cmap=ListedColormap(colours), vmin=-0.5, vmax=len(legend) - 0.5,
    )
    several = summary["attractors"].reshape(shape).T >= 2
    gx, gy = np.meshgrid(x, y)
    handles = [Patch(color=c, label=name) for c, name in zip(colours, legend, strict=True)]
    if several.any():
        axes.scatter(gx[several], gy[several], s=4, color="black", marker=".")
        handles.append(axes.scatter([], [], s=12, color="black", marker=".",
                                    label="coexisting attractors"))
    axes.set_xlabel(first["name"])
    axes.set_ylabel(second["name"])
    axes.set_title(_title(data))
    legend_beside(axes, handles=handles, fontsize="small", title="dominant attractor")
    return figure


def _extent(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Image extent with each cell centred on its grid value."""
    def edges(v: np.ndarray) -> tuple[float, float]:
        half = (v[-1] - v[0]) / (2 * (v.size - 1)) if v.size > 1 else 0.5
        return float(v[0] - half), float(v[-1] + half)

    return (*edges(x), *edges(y))


def _basins(data: dict[str, Any]):
    theta0, omega0 = data["axes"]["theta0"], data["axes"]["omega0"]
    labels = data["summary"]["label"].reshape(omega0.size, theta0.size)
    attractors = tuple(
        Attractor(a["name"], Regime(a["regime"], a["period"], a["name"]),
                  np.asarray(a["points"]).reshape(-1, 2), a["fraction"])
        for a in data["summary_info"]["attractors"]
    )
    basin_map = BasinMap(theta0, omega0, labels, attractors)
    return plot_basins(basin_map, title=_title(data))
