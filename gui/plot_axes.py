"""Axes labelled and scaled through the display-unit table (gui.units)."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg

from gui.units import DisplayUnit, axis_range


def label_axis(plot: pg.PlotWidget, side: str, name: str, unit: DisplayUnit | None) -> None:
    """Label an axis with the quantity and its display unit (no SI prefix added by the plot)."""
    axis = plot.getAxis(side)
    axis.enableAutoSIPrefix(False)
    plot.setLabel(side, f"{name} ({unit.unit})" if unit is not None and unit.unit else name)


def fit_axes(
    plot: pg.PlotWidget, x: np.ndarray, y: np.ndarray, x_unit: DisplayUnit, y_unit: DisplayUnit
) -> None:
    """Scale both axes to the points drawn (display units), never below the minimum spans."""
    for limits, set_range in (
        (axis_range(x, x_unit.minimum_span), plot.setXRange),
        (axis_range(y, y_unit.minimum_span), plot.setYRange),
    ):
        if limits is not None:
            set_range(*limits, padding=0)
