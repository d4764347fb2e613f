"""Angle and table displacement against time: a scrolling window with the tach pulses marked."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from gui.decimate import min_max_decimate
from gui.live_data import LiveData

ANGLE_PEN = pg.mkPen("#1f4e9c", width=1)
TABLE_PEN = pg.mkPen("#2a7a2a", width=1)
TACH_PEN = pg.mkPen("#c03030", width=1)


class TimeTraceView(QWidget):
    """Two linked plots (angle in rad, table in mm) of the last ``window_s`` seconds."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window_s = QDoubleSpinBox(minimum=0.5, maximum=30.0, value=5.0, suffix=" s")
        self.window_s.setToolTip("how many seconds the traces show")
        controls = QHBoxLayout()
        controls.addWidget(QLabel("Window"))
        controls.addWidget(self.window_s)
        controls.addStretch(1)
        self.angle_plot = pg.PlotWidget()
        self.angle_plot.setLabel("left", "angle", units="rad")
        # no grid on the live traces: alpha-blended grid lines cost more than the data to paint
        self.table_plot = pg.PlotWidget()
        self.table_plot.setLabel("left", "table", units="m")
        self.table_plot.setLabel("bottom", "time", units="s")
        self.table_plot.setXLink(self.angle_plot)
        self.angle_curve = self.angle_plot.plot(pen=ANGLE_PEN)
        self.table_curve = self.table_plot.plot(pen=TABLE_PEN)
        self.tach_marks = pg.PlotDataItem(pen=TACH_PEN, connect="pairs")
        self.angle_plot.addItem(self.tach_marks)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(controls)
        layout.addWidget(self.angle_plot, 3)
        layout.addWidget(self.table_plot, 2)
        self.points_drawn = 0  # after decimation, last frame (for tests and the benchmark)

    def refresh(self, data: LiveData) -> None:
        """Redraw from the newest data (decimated to the plot's pixel width)."""
        fs = data.sample_rate_hz
        n = int(self.window_s.value() * fs)
        columns = max(100, self.angle_plot.width())
        drawn = 0
        angle_index, angle = data.angle.latest(n)
        if angle.size:
            t, y = min_max_decimate(angle_index / fs, angle, columns)
            self.angle_curve.setData(t, y)
            drawn += t.size
            self._draw_tach(data, angle_index[0], angle_index[-1], float(y.min()), float(y.max()))
        table_index, table = data.table.latest(n)
        if table.size:
            t, y = min_max_decimate(table_index / fs, table, columns)
            self.table_curve.setData(t, y)
            drawn += t.size
        self.points_drawn = drawn

    def _draw_tach(self, data: LiveData, first: int, last: int, low: float, high: float) -> None:
        edges = (
            np.fromiter((e for e in reversed(data.tach_edges) if e >= first), dtype=np.int64)[::-1]
            if data.tach_edges
            else np.zeros(0, np.int64)
        )
        edges = edges[edges <= last]
        if not edges.size:
            self.tach_marks.setData([], [])
            return
        span = max(high - low, 1e-6)
        x = np.repeat(edges / data.sample_rate_hz, 2)
        y = np.tile([high + 0.02 * span, high + 0.12 * span], edges.size)
        self.tach_marks.setData(x, y)
