"""Basins of attraction on a grid of initial states (theta0, theta_dot0).

Every grid point is simulated past its transient; its final Poincare orbit is matched
against a catalogue of the attractors found so far (same period and the same cycle
points for periodic orbits; overlapping point clouds otherwise).  An orbit that
matches nothing is classified (:func:`analysis.dynamics.regime.classify_regime`) and
added to the catalogue under a name such as "period-2" or "chaotic".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.dynamics.chaos01 import MIN_SAMPLES, zero_one_k
from analysis.dynamics.regime import (
    Regime,
    classify_regime,
    closing_period,
    stacked_recurrence_distances,
)
from analysis.dynamics.sweeps import PoincareSettings, run_poincare
from analysis.figure_style import legend_beside, save_figure
from analysis.model import Model
from analysis.progress import ProgressCounts

if TYPE_CHECKING:  # matplotlib is imported by the plot functions only (slow import)
    from matplotlib.figure import Figure

NO_ATTRACTOR = -1  # the run left the model's regime (over the top) or failed


@dataclass(frozen=True)
class Attractor:
    """One attractor of the catalogue: its name, its regime and Poincare points (theta, theta')."""

    name: str
    regime: Regime
    points: np.ndarray  # (k, 2): the cycle for periodic attractors, a cloud otherwise
    basin_fraction: float


@dataclass(frozen=True)
class BasinMap:
    """Attractor index per initial state: ``labels[i, j]`` for theta_dot0[i], theta0[j].

    ``labels`` holds indices into ``attractors`` or ``NO_ATTRACTOR`` (-1).
    """

    theta0: np.ndarray
    theta_dot0: np.ndarray
    labels: np.ndarray
    attractors: tuple[Attractor, ...]


def basins_of_attraction(
    model: Model,
    theta0_values: Sequence[float] | np.ndarray,
    theta_dot0_values: Sequence[float] | np.ndarray,
    *,
    transient_periods: int = 200,
    record_periods: int = 64,
    tolerance: float = 1e-3,
    match_tolerance: float = 0.02,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    workers: int | None = None,
    progress: ProgressCounts | None = None,
) -> BasinMap:
    """Which attractor each initial state (at drive phase 0) settles on.

    ``tolerance`` (relative to the attractor size) decides periodicity as in the
    classifier; ``match_tolerance`` (relative to the size of all orbits together)
    decides that two orbits are the same attractor.  ``progress`` is told the runs done
    of all (a :class:`~analysis.progress.Progress`) as runs finish.
    """
    theta0 = np.asarray(theta0_values, dtype=float).ravel()
    theta_dot0 = np.asarray(theta_dot0_values, dtype=float).ravel()
    if theta0.size == 0 or theta_dot0.size == 0:
        raise ValueError("the grid of initial states is empty")
    if record_periods < 50:
        raise ValueError(
            f"record_periods = {record_periods}: non-periodic attractors are named by the 0-1 "
            "test, which needs at least 50 Poincare samples"
        )
    if model.drive.frequency_hz <= 0 or not model.drive.is_forced:
        raise ValueError("basins need a forced model (drive amplitude and frequency > 0)")
    grid_theta, grid_rate = np.meshgrid(theta0, theta_dot0)
    initial = np.column_stack([grid_theta.ravel(), grid_rate.ravel()])
    packed = np.tile(model.pack(), (initial.shape[0], 1))
    runs = run_poincare(packed, initial,
                        PoincareSettings(transient_periods, record_periods, rtol, atol),
                        workers=workers, progress=progress)
    ok = np.array([status == "ok" for status in runs.status])
    labels, attractors = identify_attractors(
        runs.theta, runs.theta_dot, ok=ok, tolerance=tolerance, match_tolerance=match_tolerance
    )
    return BasinMap(theta0, theta_dot0, labels.reshape(grid_theta.shape), attractors)


def identify_attractors(
    theta: np.ndarray,
    theta_dot: np.ndarray,
    *,
    ok: np.ndarray | None = None,
    tolerance: float = 1e-3,
    match_tolerance: float = 0.02,
) -> tuple[np.ndarray, tuple[Attractor, ...]]:
    """Group settled Poincare orbits (rows of (n, k) arrays) by the attractor they lie on.

    Returns a label per orbit (index into the catalogue, ``NO_ATTRACTOR`` for rows
    marked not ``ok`` or containing NaN) and the catalogue, in order of discovery.
    Non-periodic orbits need k >= 50 samples for the 0-1 test that names them.
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    (result,) = identify_attractor_groups(
        theta, theta_dot, [theta.shape[0]], ok=ok, tolerance=tolerance,
        match_tolerance=match_tolerance,
    )
    return result


def identify_attractor_groups(
    theta: np.ndarray,
    theta_dot: np.ndarray,
    ends: Sequence[int] | np.ndarray,
    *,
    ok: np.ndarray | None = None,
    tolerance: float = 1e-3,
    match_tolerance: float = 0.02,
) -> list[tuple[np.ndarray, tuple[Attractor, ...]]]:
    """:func:`identify_attractors` of each group of orbits, rows ``ends[g-1]:ends[g]``
    (groups in order, the first from row 0), each group on its own as if alone: its
    labels and its catalogue.  The orbits' recurrence is computed for all groups at once,
    which is what makes many small groups (a regime map's points) quick.
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    theta_dot = np.atleast_2d(np.asarray(theta_dot, dtype=float))
    if theta.shape != theta_dot.shape:
        raise ValueError(f"theta {theta.shape} and theta_dot {theta_dot.shape} differ in shape")
    ok = np.ones(theta.shape[0], dtype=bool) if ok is None else np.asarray(ok, dtype=bool)
    ends = np.asarray(ends, dtype=np.int64)
    starts = np.concatenate([[0], ends[:-1]]).astype(np.int64)
    finite = ok & np.all(np.isfinite(theta), axis=1) & np.all(np.isfinite(theta_dot), axis=1)
    # One scale per group, so that "same attractor" means the same thing across the group
    group_scales = []
    for first, stop in zip(starts, ends, strict=True):
        rows = first + np.flatnonzero(finite[first:stop])
        group_scales.append(_scale(theta[rows], theta_dot[rows]) if rows.size else np.ones(2))
    scales = np.repeat(group_scales, ends - starts, axis=0).reshape(-1, 2)  # per orbit
    orbits = np.stack([theta, theta_dot], axis=-1)
    normalised = np.zeros_like(orbits)
    normalised[finite] = orbits[finite] / scales[finite][:, None, :]
    recurrence = np.full((theta.shape[0], MAX_PERIOD), np.inf)
    recurrence[finite] = stacked_recurrence_distances(normalised[finite], MAX_PERIOD)
    closes = recurrence <= tolerance
    period = np.where(closes.any(axis=1), np.argmax(closes, axis=1) + 1, 0)
    groups = []
    for first, stop, scale in zip(starts, ends, group_scales, strict=True):
        rows = slice(first, stop)
        labels, catalogue = _identify(
            normalised[rows], recurrence[rows], period[rows], finite[rows], scale, tolerance,
            match_tolerance,
        )
        groups.append((labels, catalogue))
    # the regimes of the new attractors, with the 0-1 test of those that do not close in
    # one call for them all
    entries = [(first, entry) for first, (_, catalogue) in zip(starts, groups, strict=True)
               for entry in catalogue]
    rows = [first + entry.row for first, entry in entries if entry.period is None]
    if theta.shape[1] < MIN_SAMPLES:  # classify_regime does without the test
        rows = []
    K = dict(zip(rows, zero_one_k(theta[rows]) if rows else [], strict=True))
    out = []
    for first, (labels, catalogue) in zip(starts, groups, strict=True):
        counts = np.bincount(labels[labels >= 0], minlength=len(catalogue))
        attractors: list[Attractor] = []
        for k, entry in enumerate(catalogue):
            row = first + entry.row
            regime = classify_regime(
                orbits[row], tolerance=tolerance, scale=scales[row], recurrence=recurrence[row],
                K=K.get(row),
            )
            name = _unique_name(regime.short_name, attractors)
            attractors.append(
                Attractor(name, regime, entry.points, float(counts[k]) / labels.size)
            )
        out.append((labels, tuple(attractors)))
    return out


MAX_PERIOD = 16  # the longest period an orbit is matched by


@dataclass
class _Entry:
    """An attractor found in a group: its first orbit (``row`` in the group), the period
    its regime will have (None: it does not close), its points (normalised, for
    matching; ``points``: in the orbits' units) and their tree, built when first needed."""

    row: int
    period: int | None
    candidate: np.ndarray
    points: np.ndarray
    tree: Any = None  # a scipy.spatial.cKDTree of candidate, for large sets


def _scale(theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
    """The size of a group's orbits (rows), per coordinate: spread or RMS, whichever is
    larger (a single period-1 attractor has no spread); 1 where both are 0."""
    everything = np.column_stack([theta.ravel(), theta_dot.ravel()])
    scale = np.maximum(np.ptp(everything, axis=0), np.sqrt(np.mean(everything**2, axis=0)))
    return np.where(scale > 0, scale, 1.0)


def _identify(normalised, recurrence, period, finite, scale, tolerance, match_tolerance):
    """Label each orbit of a group with a catalogue index, building the catalogue on the
    way (the regimes of its entries are named afterwards)."""
    labels = np.full(normalised.shape[0], NO_ATTRACTOR, dtype=np.int64)
    catalogue: list[_Entry] = []
    samples = normalised.shape[1]
    for i in np.flatnonzero(finite):
        k = int(period[i]) or None
        candidate = normalised[i, -k:] if k else normalised[i]
        found = _match(candidate, k, catalogue, match_tolerance)
        if found is None:
            closes = closing_period(recurrence[i], samples, tolerance=tolerance)
            catalogue.append(_Entry(int(i), closes, candidate, candidate * scale))
            found = len(catalogue) - 1
        labels[i] = found
    return labels, catalogue


def _match(candidate, period, catalogue, match_tolerance):
    """Catalogue index of the attractor the normalised orbit lies on, or None."""
    for k, entry in enumerate(catalogue):
        if entry.period != period:
            continue
        distance = _nearest_distances(candidate, entry)
        if period is not None:
            if np.max(distance) <= match_tolerance:
                return k
        elif np.median(distance) <= match_tolerance:
            # a cloud: most new points fall among the known ones
            return k
    return None


BRUTE_FORCE_PAIRS = 1 << 16  # up to this many point pairs, every distance beats a tree


def _nearest_distances(points, entry):
    """Euclidean distance from each of ``points`` to the nearest point of ``entry``: every
    pair for small sets (the same numbers as a tree, which larger ones use)."""
    known = entry.candidate
    if points.shape[0] * known.shape[0] <= BRUTE_FORCE_PAIRS:
        dx = points[:, None, 0] - known[None, :, 0]
        dy = points[:, None, 1] - known[None, :, 1]
        return np.sqrt(np.min(dx * dx + dy * dy, axis=1))
    if entry.tree is None:
        from scipy.spatial import cKDTree  # here: most maps never need it

        entry.tree = cKDTree(known)
    return entry.tree.query(points)[0]


def _unique_name(base: str, found: list[Attractor]) -> str:
    taken = {attractor.name for attractor in found}
    if base not in taken:
        return base
    suffix = 2
    while f"{base} ({suffix})" in taken:
        suffix += 1
    return f"{base} ({suffix})"


def plot_basins(
    basin_map: BasinMap, *, title: str | None = None, path: str | Path | None = None
) -> Figure:
    """Colour map of the basins with a legend of attractor names (Agg); PNG when ``path`` given."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 5.5), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    count = len(basin_map.attractors)
    palette = ["#d0d0d0"] + [_COLOURS[k % len(_COLOURS)] for k in range(max(count, 1))]
    extent = (
        basin_map.theta0[0],
        basin_map.theta0[-1],
        basin_map.theta_dot0[0],
        basin_map.theta_dot0[-1],
    )
    axes.imshow(
        basin_map.labels + 1,
        origin="lower",
        extent=extent,
        aspect="auto",
        interpolation="nearest",
        cmap=ListedColormap(palette[: count + 1]),
        vmin=-0.5,
        vmax=count + 0.5,
    )
    for k, attractor in enumerate(basin_map.attractors):
        points = attractor.points
        axes.plot(points[:, 0], points[:, 1], "o", color="black", markersize=3)
        axes.plot(
            [],
            [],
            "s",
            color=palette[k + 1],
            label=f"{attractor.name} ({100 * attractor.basin_fraction:.0f} %)",
        )
    if np.any(basin_map.labels == NO_ATTRACTOR):
        axes.plot([], [], "s", color=palette[0], label="left the model (over the top)")
    axes.set_xlabel("theta0 [rad]")
    axes.set_ylabel("theta_dot0 [rad/s]")
    if title:
        axes.set_title(title)
    legend_beside(axes, fontsize="small")
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path)
    return figure


_COLOURS = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
]
