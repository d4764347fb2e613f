"""Angle and table displacement against time: a scrolling window with the tach pulses and the
sweep steps marked, in seconds from the start of the source, degrees and millimetres."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from gui.decimate import min_max_decimate
from gui.live_data import ChannelRing, LiveData
from gui.plot_axes import HandZoom, label_axis
from gui.units import DISPLAY, DisplayUnit, axis_range

ANGLE_PEN = pg.mkPen("#1f4e9c", width=1)
TABLE_PEN = pg.mkPen("#2a7a2a", width=1)
TACH_PEN = pg.mkPen("#c03030", width=1)
STEP_PEN = pg.mkPen("#808080", width=1, style=Qt.PenStyle.DashLine)
MAX_STEP_MARKERS = 24  # steps inside one window (a window holds a few steps at most)
TACH_BAND = 0.15  # the tach marks sit in this top fraction of the angle plot


class TimeTraceView(QWidget):
    """Two linked plots (angle, table) of the last ``window_s`` seconds, scaled to the data."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window_s = QDoubleSpinBox(minimum=0.5, maximum=30.0, value=5.0, suffix=" s")
        self.window_s.setToolTip("how many seconds the traces show")
        controls = QHBoxLayout()
        controls.addWidget(QLabel("Window"))
        controls.addWidget(self.window_s)
        controls.addStretch(1)
        self.angle_plot = pg.PlotWidget()
        label_axis(self.angle_plot, "left", "angle", DISPLAY["angle"])
        # no grid on the live traces: alpha-blended grid lines cost more than the data to paint
        self.table_plot = pg.PlotWidget()
        label_axis(self.table_plot, "left", "table", DISPLAY["displacement"])
        label_axis(self.table_plot, "bottom", "time from the start", DISPLAY["time"])
        self.table_plot.setXLink(self.angle_plot)
        self.hand_zoom = HandZoom(self.angle_plot, self.table_plot)
        self.angle_curve = self.angle_plot.plot(pen=ANGLE_PEN)
        self.table_curve = self.table_plot.plot(pen=TABLE_PEN)
        self.tach_marks = pg.PlotDataItem(pen=TACH_PEN, connect="pairs")
        self.angle_plot.addItem(self.tach_marks)
        self.step_markers = [
            pg.InfiniteLine(angle=90, pen=STEP_PEN, label="", labelOpts={"position": 0.92})
            for _ in range(MAX_STEP_MARKERS)
        ]
        for marker in self.step_markers:
            marker.setVisible(False)
            self.angle_plot.addItem(marker)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(controls)
        layout.addWidget(self.angle_plot, 3)
        layout.addWidget(self.table_plot, 2)
        self.points_drawn = 0  # after decimation, last frame (for tests and the benchmark)

    def refresh(self, data: LiveData) -> None:
        """Redraw from the newest data (decimated to the plot's pixel width)."""
        n = int(self.window_s.value() * data.sample_rate_hz)
        columns = max(100, self.angle_plot.width())
        angle_drawn, angle_index = self._draw(data, data.angle, n, columns, self.angle_curve,
                                 self.angle_plot, DISPLAY["angle"], TACH_BAND)
        table_drawn, _ = self._draw(data, data.table, n, columns, self.table_curve,
                                 self.table_plot, DISPLAY["displacement"], 0.0)
        self.points_drawn = angle_drawn + table_drawn
        if angle_index.size:
            end_s = float(data.seconds(angle_index[-1]))
            start_s = max(0.0, end_s - self.window_s.value())
            if not self.hand_zoom.active:
                self.angle_plot.setXRange(start_s, start_s + self.window_s.value(), padding=0)
            self._draw_tach(data, int(angle_index[0]), int(angle_index[-1]))
            self._draw_steps(data, int(angle_index[0]), int(angle_index[-1]))

    def _draw(self, data: LiveData, ring: ChannelRing, n: int, columns: int,
              curve: pg.PlotDataItem, plot: pg.PlotWidget, unit: DisplayUnit,
              headroom: float) -> tuple[int, np.ndarray]:
        """Draw one channel in display units, its axis fitted to what is shown plus
        ``headroom`` (a fraction of the plot kept free at the top); returns the points
        drawn and the sample indices shown."""
        index, values = ring.latest(n)
        if not values.size:
            return 0, index
        t, y = min_max_decimate(data.seconds(index), unit.show(values), columns)
        curve.setData(t, y)
        limits = axis_range(y, unit.minimum_span)
        if limits is not None and not self.hand_zoom.active:
            low, high = limits
            plot.setYRange(low, high + headroom / (1.0 - headroom) * (high - low), padding=0)
        return int(t.size), index

    def _draw_tach(self, data: LiveData, first: int, last: int) -> None:
        edges = (
            np.fromiter((e for e in reversed(data.tach_edges) if e >= first), dtype=np.int64)[::-1]
            if data.tach_edges
            else np.zeros(0, np.int64)
        )
        edges = edges[edges <= last]
        if not edges.size:
            self.tach_marks.setData([], [])
            return
        low, high = self.angle_plot.viewRange()[1]
        band = TACH_BAND * (high - low)
        x = np.repeat(data.seconds(edges), 2)
        y = np.tile([high - 0.8 * band, high - 0.2 * band], edges.size)
        self.tach_marks.setData(x, y)

    def _draw_steps(self, data: LiveData, first: int, last: int) -> None:
        """A dashed line where each sweep step inside the window began, labelled with it."""
        shown = sorted((at, step) for at, step in data.step_starts().items() if first <= at <= last)
        for marker, (at, step) in zip(self.step_markers, shown[-MAX_STEP_MARKERS:], strict=False):
            marker.setValue(float(data.seconds(at)))
            marker.label.setFormat(f"step {step + 1}")
            marker.setVisible(True)
        for marker in self.step_markers[len(shown[-MAX_STEP_MARKERS:]) :]:
            marker.setVisible(False)
