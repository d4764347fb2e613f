"""Poincare section from the tach pulses: one point per drive period, accumulating until cleared.

A period-1 response is one dot, period 2 two dots, chaos a fractal cloud.  Shown as
angle against angular velocity, or as the delayed-angle map (theta_k, theta_k+1).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from analysis.dynamics.poincare import delayed_map, poincare_from_pulses
from gui.live_data import LiveData
from gui.plot_axes import HandZoom, fit_axes, label_axis
from gui.units import DISPLAY

MODES = ("angle vs angular velocity", "angle vs delayed angle")
DERIVATIVE_WINDOW = 15
MAX_POINTS = 50_000


class PoincareAccumulator:
    """Turns new tach edges into section points as soon as the samples around them arrived."""

    def __init__(self) -> None:
        self.theta = np.zeros(0)
        self.theta_dot = np.zeros(0)
        self._last_edge = -1
        self._generation = -1

    def clear(self) -> None:
        """Drop the points collected so far (keep collecting from the next pulse)."""
        self.theta = np.zeros(0)
        self.theta_dot = np.zeros(0)

    def update(self, data: LiveData) -> int:
        """Add the points of pulses whose neighbourhood is now complete; returns how many."""
        if data.generation != self._generation:
            self._generation = data.generation
            self._last_edge = -1
            self.clear()
        end = data.angle.end_index
        if end is None or not data.tach_edges:
            return 0
        margin = 2 * DERIVATIVE_WINDOW  # samples needed on each side of a pulse
        pending = [e for e in data.tach_edges if e > self._last_edge and e + margin <= end]
        if not pending:
            return 0
        first_needed = pending[0] - margin
        index, theta = data.angle.since(first_needed)
        self._last_edge = pending[-1]
        if theta.size < 2 * margin or np.any(np.diff(index) != 1):
            return 0  # a gap or an overwritten stretch: skip rather than interpolate across it
        positions = np.asarray(pending, dtype=float) - index[0]
        positions = positions[(positions >= 0) & (positions <= theta.size - 1)]
        if not positions.size:
            return 0
        section = poincare_from_pulses(
            theta, data.sample_rate_hz, positions, derivative_window_samples=DERIVATIVE_WINDOW
        )
        self.theta = np.concatenate([self.theta, section.theta])[-MAX_POINTS:]
        self.theta_dot = np.concatenate([self.theta_dot, section.theta_dot])[-MAX_POINTS:]
        return int(section.theta.size)


class PoincareView(QWidget):
    """Scatter of the accumulated section; a button clears it."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.accumulator = PoincareAccumulator()
        self._drawn: tuple = ()
        self.mode = QComboBox()
        self.mode.addItems(MODES)
        self.clear_button = QPushButton("Clear")
        self.clear_button.setToolTip("forget the points so far (e.g. after changing the drive)")
        self.clear_button.clicked.connect(self.accumulator.clear)
        self.count = QLabel("0 points")
        controls = QHBoxLayout()
        controls.addWidget(QLabel("Show"))
        controls.addWidget(self.mode)
        controls.addWidget(self.clear_button)
        controls.addWidget(self.count)
        controls.addStretch(1)
        self.plot = pg.PlotWidget()
        self.hand_zoom = HandZoom(self.plot)
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.scatter = pg.ScatterPlotItem(size=4, pen=None, brush=pg.mkBrush(30, 60, 160, 160))
        self.newest = pg.ScatterPlotItem(size=9, pen=pg.mkPen("#c03030"), brush=None)
        self.plot.addItem(self.scatter)
        self.plot.addItem(self.newest)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(controls)
        layout.addWidget(self.plot)

    def collect(self, data: LiveData) -> None:
        """Take new pulses (cheap; done every frame even when the view is hidden)."""
        self.accumulator.update(data)

    def refresh(self, data: LiveData) -> None:
        """Redraw the points (only when there are new ones or the choice of axes changed)."""
        theta, rate = self.accumulator.theta, self.accumulator.theta_dot
        drawn = (theta.size, float(theta[-1]) if theta.size else 0.0, self.mode.currentIndex())
        if drawn == self._drawn:
            return
        self._drawn = drawn
        self.count.setText(f"{theta.size} points")
        angle = DISPLAY["angle"]
        if self.mode.currentIndex() == 0:
            y_unit = DISPLAY["angular_velocity"]
            x, y = theta, rate
            label_axis(self.plot, "left", "angular velocity", y_unit)
        else:
            y_unit = angle
            x, y = delayed_map(theta, 1) if theta.size > 1 else (np.zeros(0), np.zeros(0))
            label_axis(self.plot, "left", "next angle", y_unit)
        label_axis(self.plot, "bottom", "angle at the pulse", angle)
        x, y = angle.show(x), y_unit.show(y)
        self.scatter.setData(x, y)
        self.newest.setData(x[-1:], y[-1:])
        fit_axes(self.plot, x, y, angle, y_unit, self.hand_zoom)
