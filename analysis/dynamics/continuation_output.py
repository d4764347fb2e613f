"""What a continuation leaves behind: the HDF5 file of its branches and events, and its figure.

File layout (all float64 unless said)::

    /branches/<i>/parameter           (n,)  value of the varied parameter
    /branches/<i>/theta, theta_dot    (n,)  state at drive phase 0 [rad, rad/s]
    /branches/<i>/multipliers_real, multipliers_imag   (n, 2), largest modulus first
    /branches/<i>/stable              (n,)  int8, 1 when every multiplier is inside |z| = 1
    /branches/<i>/max_angle_rad, barrier_distance_rad, apex_distance_rad,
                  impact_speed_rad_s, jacobian_error   (n,)
    /branches/<i>/contacts            (n,)  int32, contacts per k periods
    /branches/<i>/section_theta       (n, k) theta at drive phase 0 of the orbit's k periods
      attributes: periods (k), origin, stop_reason
    /events/kind                      (m,)  strings: period_doubling, fold, branch_point, grazing
    /events/branch, periods           (m,)  int32
    /events/parameter, parameter_low, parameter_high, theta, theta_dot   (m,)
    /events/multipliers_real, multipliers_imag   (m, 2)
    root attributes: parameter, bounds, seconds, seconds_per_point, map_rtol, jacobians
                     (how the Jacobians were taken: sensitivities, or differences and why),
                     model_json (rig, drive, barrier, causes), provenance_json,
                     overlays_json (what the figure drew over the branches: file or
                     computation, and the directions)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from analysis import quantities as q
from analysis.dynamics.bifurcation import BifurcationDiagram, diagram_style
from analysis.dynamics.continuation import BifurcationEvent, ContinuationResult
from analysis.figure_style import legend_beside, save_figure
from analysis.json_output import to_json_text
from analysis.model import Model

if TYPE_CHECKING:  # matplotlib is imported by the plot function only (slow import)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

POINT_COLUMNS = ("max_angle_rad", "barrier_distance_rad", "apex_distance_rad",
                 "impact_speed_rad_s", "jacobian_error")


def model_summary(model: Model) -> dict[str, Any]:
    """The model as plain values, for the file's attributes."""
    return {
        "rig": model.rig.as_dict(),
        "drive": {q.frequency_hz: model.drive.frequency_hz,
                  q.amplitude_m: model.drive.amplitude_m},
        "barrier": model.barrier,
        "causes": {name: dict(values) for name, values in model.extensions.items()},
    }


def write_continuation(path: str | Path, result: ContinuationResult, model: Model,
                       provenance: dict[str, Any],
                       overlays: Sequence[dict[str, Any]] = ()) -> None:
    """Write the branches and events of ``result`` (layout in the module docstring);
    ``overlays`` describes what the figure drew over them."""
    with h5py.File(path, "w") as handle:
        handle.attrs["parameter"] = result.parameter
        handle.attrs["bounds"] = np.array(result.bounds)
        handle.attrs["seconds"] = result.seconds
        handle.attrs["seconds_per_point"] = result.seconds_per_point
        handle.attrs["map_rtol"] = result.map_rtol
        handle.attrs["jacobians"] = result.jacobians
        handle.attrs["model_json"] = to_json_text(model_summary(model), one_line=True)
        handle.attrs["provenance_json"] = to_json_text(provenance, one_line=True)
        handle.attrs["overlays_json"] = to_json_text(list(overlays), one_line=True)
        branches = handle.create_group("branches")
        for i, branch in enumerate(result.branches):
            group = branches.create_group(str(i))
            group.attrs["periods"] = branch.periods
            group.attrs["origin"] = branch.origin
            group.attrs["stop_reason"] = branch.stop_reason
            states = branch.states
            multipliers = branch.multipliers
            group["parameter"] = branch.values
            group["theta"] = states[:, 0]
            group["theta_dot"] = states[:, 1]
            group["multipliers_real"] = multipliers.real
            group["multipliers_imag"] = multipliers.imag
            group["stable"] = branch.stable.astype(np.int8)
            group["contacts"] = branch.column("contacts").astype(np.int32)
            for name in POINT_COLUMNS:
                group[name] = branch.column(name).astype(float)
            group["section_theta"] = branch.column("section_theta").reshape(-1, branch.periods)
        events = handle.create_group("events")
        found = result.events
        events["kind"] = np.array([e.kind for e in found], dtype=h5py.string_dtype())
        events["branch"] = np.array([e.branch for e in found], dtype=np.int32)
        events["periods"] = np.array([e.periods for e in found], dtype=np.int32)
        events["parameter"] = np.array([e.value for e in found], dtype=float)
        events["parameter_low"] = np.array([e.bracket[0] for e in found], dtype=float)
        events["parameter_high"] = np.array([e.bracket[1] for e in found], dtype=float)
        states = np.array([e.point.state for e in found]).reshape(-1, 2)
        events["theta"] = states[:, 0]
        events["theta_dot"] = states[:, 1]
        multipliers = np.array([e.point.multipliers for e in found]).reshape(-1, 2)
        events["multipliers_real"] = multipliers.real
        events["multipliers_imag"] = multipliers.imag


_EVENT_MARKERS = {"period_doubling": ("o", "red"), "fold": ("s", "#8e24aa"),
                  "branch_point": ("D", "#f9a825"), "grazing": ("^", "#2e7d32")}
# branch colours: none of the brute-force diagrams' blue and orange nor the events' colours
_PALETTE = ["black", "#c2185b", "#00838f", "#6d4c41", "#7cb342", "gray"]
CALLOUT_SPACING = 0.035  # least distance of two event numbers, in axes widths
MAX_LISTED_EVENTS = 14


def plot_continuation(result: ContinuationResult, *,
                      overlays: Sequence[BifurcationDiagram] = (),
                      barrier_rad: float | None = None, title: str | None = None,
                      path: str | Path | None = None, dpi: int = 120) -> Figure:
    """The branches against the parameter (Agg, no window): stable parts solid, unstable ones
    dashed, one colour per period; every event numbered along the top edge and listed in a
    table under the axes (kind, period, value, multipliers), so close events stay legible.

    The panel shows each orbit's largest angle (and the barrier at ``barrier_rad``).  With
    ``overlays`` (brute-force or recorded bifurcation diagrams) a second panel shows the
    angle at drive phase 0, the quantity those diagrams hold: the k points of each
    period-k orbit, with the diagrams' points under them.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    events = sorted(result.events, key=lambda e: e.value)
    listed = events[:MAX_LISTED_EVENTS]
    panels = 2 if overlays else 1
    table_in = 0.35 + 0.17 * (len(listed) + (len(events) > len(listed)))
    height = 0.9 + 3.6 * panels + (table_in if events else 0.0)
    figure = Figure(figsize=(9.0, height), dpi=dpi)
    FigureCanvasAgg(figure)
    bottom = (table_in + 0.1) / height if events else 0.09
    grid = figure.add_gridspec(panels, 1, left=0.09, right=0.98, top=1.0 - 0.75 / height,
                               bottom=bottom + 0.5 / height, hspace=0.12)
    top = figure.add_subplot(grid[0])
    colours = _draw_branches(top, result, lambda b: b.column("max_angle_rad")[:, None])
    if barrier_rad is not None:
        top.axhline(barrier_rad, color="0.4", linewidth=0.8, linestyle=":", label="barrier")
    top.set_ylabel("largest angle of the orbit [rad]")
    for event in events:
        marker, colour = _EVENT_MARKERS[event.kind]
        top.plot(event.value, event.point.max_angle_rad, marker=marker, color=colour,
                 linestyle="none", markersize=6, markeredgecolor="white", markeredgewidth=0.6)
    _legend_entries(top, colours, events)
    legend_beside(top, fontsize=7.5)
    axes = [top]
    if overlays:
        lower = figure.add_subplot(grid[1], sharex=top)
        for diagram in overlays:
            x, y = diagram.scatter()
            style = diagram_style(diagram.direction)
            # over the lines: where a sweep sits on a branch its points must stay visible
            lower.scatter(x, y, marker=".", linewidths=0, alpha=0.8, zorder=5, **style)
        _draw_branches(lower, result, lambda b: b.column("section_theta").reshape(
            -1, b.periods), colours)
        for event in events:
            marker, colour = _EVENT_MARKERS[event.kind]
            lower.plot(np.full(event.periods, event.value), event.point.section_theta,
                       marker=marker, color=colour, linestyle="none", markersize=5,
                       markeredgecolor="white", markeredgewidth=0.5, zorder=4)
        lower.set_ylabel("angle at drive phase 0 [rad]")
        legend = legend_beside(lower, fontsize=7.5, markerscale=4)
        for handle in legend.legend_handles:
            handle.set_alpha(1.0)
        top.tick_params(labelbottom=False)
        axes.append(lower)
    axes[-1].set_xlabel(result.parameter)
    for panel in axes:
        panel.grid(alpha=0.25, linewidth=0.5)
    top.set_xlim(*top.get_xlim())  # frozen: the callouts are placed in axes fractions
    _number_events(top, listed)
    if title:
        figure.suptitle(title, fontsize=11, y=1.0 - 0.12 / height, va="top")
    if events:
        figure.text(0.09, table_in / height, _event_table(result.parameter, events, listed),
                    family="monospace", fontsize=7.5, va="top", ha="left")
    if path is not None:
        save_figure(figure, path)
    return figure


def _draw_branches(axes: Axes, result: ContinuationResult, quantity,
                   colours: dict[int, str] | None = None) -> dict[int, str]:
    """Each branch's ``quantity`` (n, m) against the parameter, stable solid, unstable dashed;
    returns the colour of each period."""
    colours = {} if colours is None else colours
    for branch in result.branches:
        colour = colours.setdefault(branch.periods, _PALETTE[len(colours) % len(_PALETTE)])
        x, y, stable = branch.values, quantity(branch), branch.stable
        # split where stability changes, each run overlapping its neighbour by one point
        edges = [0, *(np.flatnonzero(np.diff(stable.astype(int))) + 1), x.size]
        for a, b in itertools.pairwise(edges):
            if b <= a:
                continue
            stop = min(b + 1, x.size)
            axes.plot(x[a:stop], y[a:stop], color=colour, linewidth=1.3, zorder=3,
                      linestyle="-" if stable[a] else "--")
    return colours


def _legend_entries(axes: Axes, colours: dict[int, str], events: list[BifurcationEvent]) -> None:
    """Legend-only artists: periods, stable/unstable, the kinds of events present."""
    for period, colour in colours.items():
        axes.plot([], [], color=colour, label=f"period {period}")
    axes.plot([], [], color="black", linestyle="-", label="stable")
    axes.plot([], [], color="black", linestyle="--", label="unstable")
    for kind in dict.fromkeys(event.kind for event in events):
        marker, colour = _EVENT_MARKERS[kind]
        axes.plot([], [], marker=marker, color=colour, linestyle="none",
                  label=kind.replace("_", "-"))


def spread_positions(fractions: Sequence[float], spacing: float = CALLOUT_SPACING,
                     low: float = 0.01, high: float = 0.99) -> np.ndarray:
    """Positions in [low, high], in the given (sorted) order, at least ``spacing`` apart and
    each as near its fraction as that allows (forward then backward sweep)."""
    positions = np.clip(np.asarray(fractions, dtype=float), low, high)
    for i in range(1, positions.size):
        positions[i] = max(positions[i], positions[i - 1] + spacing)
    if positions.size:
        positions[-1] = min(positions[-1], high)
    for i in range(positions.size - 2, -1, -1):
        positions[i] = min(positions[i], positions[i + 1] - spacing)
    return positions


def _number_events(axes: Axes, events: list[BifurcationEvent]) -> None:
    """Each event's number above the axes, spread apart, with a leader line to its marker."""
    lo, hi = axes.get_xlim()
    fractions = [(event.value - lo) / (hi - lo) for event in events]
    for number, (event, x) in enumerate(zip(events, spread_positions(fractions), strict=True),
                                        start=1):
        colour = _EVENT_MARKERS[event.kind][1]
        axes.annotate(str(number), (event.value, event.point.max_angle_rad),
                      xytext=(x, 1.015), textcoords="axes fraction", ha="center",
                      va="bottom", fontsize=7.5, color=colour, fontweight="bold",
                      arrowprops=dict(arrowstyle="-", color=colour, linewidth=0.5,
                                      alpha=0.7, shrinkA=0, shrinkB=3))


def _event_table(parameter: str, events: list[BifurcationEvent],
                 listed: list[BifurcationEvent]) -> str:
    """The events as aligned text lines, numbered as on the figure."""
    lines = [f" #  {'event':<16}{'period':<9}{parameter + ' (bracket)':<31}multipliers"]
    for number, event in enumerate(listed, start=1):
        period = (f"{event.periods}->{2 * event.periods}" if event.kind == "period_doubling"
                  else str(event.periods))
        width = event.bracket[1] - event.bracket[0]
        where = f"{event.value:.9g} " + (f"({width:.0e})" if math.isfinite(width)
                                         else "(not located)")
        mu = ", ".join(_complex(m) for m in event.point.multipliers)
        lines.append(f"{number:>2}  {event.kind.replace('_', '-'):<16}{period:<9}{where:<31}{mu}")
    if len(events) > len(listed):
        lines.append(f"    ... and {len(events) - len(listed)} more (in the HDF5 file)")
    return "\n".join(lines)


def _complex(value: complex) -> str:
    """A multiplier in four decimals, its imaginary part only when it has one."""
    value = complex(value)
    if abs(value.imag) < 1e-9:
        return f"{value.real:.4f}"
    return f"{value.real:.4f}{value.imag:+.4f}i"
