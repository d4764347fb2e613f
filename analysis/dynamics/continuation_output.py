"""What a continuation leaves behind: the HDF5 file of its branches and events, and its figure.

File layout (all float64 unless said):

    /branches/<i>/parameter           (n,)  value of the varied parameter
    /branches/<i>/theta, theta_dot    (n,)  state at drive phase 0 [rad, rad/s]
    /branches/<i>/multipliers_real, multipliers_imag   (n, 2), largest modulus first
    /branches/<i>/stable              (n,)  int8, 1 when every multiplier is inside |z| = 1
    /branches/<i>/max_angle_rad, barrier_distance_rad, apex_distance_rad,
                  impact_speed_rad_s, jacobian_error   (n,)
    /branches/<i>/contacts            (n,)  int32, contacts per k periods
      attributes: periods (k), origin, stop_reason
    /events/kind                      (m,)  strings: period_doubling, fold, branch_point, grazing
    /events/branch, periods           (m,)  int32
    /events/parameter, parameter_low, parameter_high, theta, theta_dot   (m,)
    /events/multipliers_real, multipliers_imag   (m, 2)
    root attributes: parameter, bounds, seconds, seconds_per_point, map_rtol,
                     model_json (rig, drive, barrier, causes), provenance_json
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from analysis.dynamics.continuation import ContinuationResult
from analysis.model import Model

if TYPE_CHECKING:  # matplotlib is imported by the plot function only (slow import)
    from matplotlib.figure import Figure

POINT_COLUMNS = ("max_angle_rad", "barrier_distance_rad", "apex_distance_rad",
                 "impact_speed_rad_s", "jacobian_error")


def model_summary(model: Model) -> dict[str, Any]:
    """The model as plain values, for the file's attributes."""
    return {
        "rig": model.rig.as_dict(),
        "drive": {"frequency_hz": model.drive.frequency_hz,
                  "amplitude_m": model.drive.amplitude_m},
        "barrier": model.barrier,
        "causes": {name: dict(values) for name, values in model.extensions.items()},
    }


def write_continuation(path: str | Path, result: ContinuationResult, model: Model,
                       provenance: dict[str, Any]) -> None:
    """Write the branches and events of ``result`` (layout in the module docstring)."""
    with h5py.File(path, "w") as handle:
        handle.attrs["parameter"] = result.parameter
        handle.attrs["bounds"] = np.array(result.bounds)
        handle.attrs["seconds"] = result.seconds
        handle.attrs["seconds_per_point"] = result.seconds_per_point
        handle.attrs["map_rtol"] = result.map_rtol
        handle.attrs["model_json"] = json.dumps(model_summary(model))
        handle.attrs["provenance_json"] = json.dumps(provenance)
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


_EVENT_MARKERS = {"period_doubling": ("o", "tab:red"), "fold": ("s", "tab:purple"),
                  "branch_point": ("D", "tab:brown"), "grazing": ("^", "tab:green")}


def plot_continuation(result: ContinuationResult, *, title: str | None = None,
                      path: str | Path | None = None) -> Figure:
    """Largest angle of each orbit against the parameter: stable parts solid, unstable ones
    dashed, one colour per period, every event marked and named (Agg, no window)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9.0, 5.5), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    colours = {}
    palette = ["tab:blue", "tab:orange", "tab:cyan", "tab:olive", "tab:pink", "tab:gray"]
    for branch in result.branches:
        colour = colours.setdefault(branch.periods, palette[len(colours) % len(palette)])
        x, y, stable = branch.values, branch.column("max_angle_rad"), branch.stable
        # split where stability changes, each run overlapping its neighbour by one point
        edges = [0, *(np.flatnonzero(np.diff(stable.astype(int))) + 1), x.size]
        for a, b in itertools.pairwise(edges):
            if b <= a:
                continue
            stop = min(b + 1, x.size)
            axes.plot(x[a:stop], y[a:stop], color=colour, linewidth=1.4,
                      linestyle="-" if stable[a] else "--")
    for period, colour in colours.items():
        axes.plot([], [], color=colour, label=f"period {period}")
    axes.plot([], [], color="black", linestyle="-", label="stable")
    axes.plot([], [], color="black", linestyle="--", label="unstable")
    seen = set()
    for event in result.events:
        marker, colour = _EVENT_MARKERS[event.kind]
        label = None if event.kind in seen else event.kind.replace("_", "-")
        seen.add(event.kind)
        axes.plot(event.value, event.point.max_angle_rad, marker=marker, color=colour,
                  linestyle="none", markersize=7, label=label)
        axes.annotate(f"{event.label} {event.value:.6g}", (event.value, event.point.max_angle_rad),
                      textcoords="offset points", xytext=(4, 4), fontsize=7, color=colour)
    axes.set_xlabel(result.parameter)
    axes.set_ylabel("largest angle of the orbit [rad]")
    if title:
        axes.set_title(title)
    axes.legend(loc="best", fontsize=8)
    figure.tight_layout()
    if path is not None:
        figure.savefig(Path(path), format="png")
    return figure
