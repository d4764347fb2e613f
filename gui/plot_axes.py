"""Axes labelled and scaled through the display-unit table (gui.units); zoomed by hand, they
stay where the user put them until the plot's auto-range button hands them back."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg

from gui.units import DisplayUnit, axis_range


def label_axis(plot: pg.PlotWidget, side: str, name: str, unit: DisplayUnit | None) -> None:
    """Label an axis with the quantity and its display unit (no SI prefix added by the plot)."""
    axis = plot.getAxis(side)
    axis.enableAutoSIPrefix(False)
    plot.setLabel(side, f"{name} ({unit.unit})" if unit is not None and unit.unit else name)


class HandZoom:
    """Whether the user zoomed or panned one of ``plots`` by hand (wheel or drag): the views
    then stop fitting the axes to the data until the plot's "A" button is clicked."""

    def __init__(self, *plots: pg.PlotWidget) -> None:
        self.active = False
        for plot in plots:
            plot.getViewBox().sigRangeChangedManually.connect(self._take)
            plot.getPlotItem().autoBtn.clicked.connect(self._give_back)

    def _take(self, *_: object) -> None:
        self.active = True

    def _give_back(self, *_: object) -> None:
        self.active = False


def fit_axes(
    plot: pg.PlotWidget, x: np.ndarray, y: np.ndarray, x_unit: DisplayUnit, y_unit: DisplayUnit,
    hand: HandZoom | None = None,
) -> None:
    """Scale both axes to the points drawn (display units), never below the minimum spans;
    left alone while ``hand`` says the user holds them."""
    if hand is not None and hand.active:
        return
    for limits, set_range in (
        (axis_range(x, x_unit.minimum_span), plot.setXRange),
        (axis_range(y, y_unit.minimum_span), plot.setYRange),
    ):
        if limits is not None:
            set_range(*limits, padding=0)
