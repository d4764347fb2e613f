"""The measured bifurcation diagram of a live sweep, growing step by step: each completed
step's stroboscopic points over its swept value (the way down beside the way up) and, in a
table, its regime."""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QLabel,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from gui.live_sweep import LiveStep, diagram_points
from gui.plot_axes import label_axis
from gui.units import DISPLAY

UP_COLOUR, DOWN_COLOUR = "#1f4e9c", "#d06000"
COLUMNS = ("step", "direction", "setting", "regime", "points", "judged on")


class SweepDiagramView(QWidget):
    """Steps are added as they are judged
    (:meth:`~gui.views.sweep_view.SweepDiagramView.add_step`);
    :meth:`~gui.views.sweep_view.SweepDiagramView.start` begins a new sweep."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.state = QLabel("no sweep yet: run one from the Sweep panel")
        self.state.setWordWrap(True)
        self.plot = pg.PlotWidget()
        label_axis(self.plot, "left", "angle at drive phase 0", DISPLAY["angle"])
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(COLUMNS)
        self.table.verticalHeader().setVisible(False)
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.plot)
        splitter.addWidget(self.table)
        splitter.setSizes([350, 150])
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.state)
        layout.addWidget(splitter, 1)
        self.steps: list[LiveStep] = []
        self.unit = DISPLAY["frequency"]
        self._scatter = {+1: self._points(UP_COLOUR, "way up"), -1: self._points(DOWN_COLOUR,
                                                                                 "way down")}
        self.start("frequency")

    def _points(self, colour: str, name: str) -> pg.ScatterPlotItem:
        item = pg.ScatterPlotItem(size=5, pen=None, brush=pg.mkBrush(colour), name=name)
        self.plot.addItem(item)
        return item

    def start(self, parameter: str) -> None:
        """Forget the last sweep; a new one sweeps ``parameter`` ('frequency', 'amplitude')."""
        self.steps.clear()
        self.unit = DISPLAY["frequency" if parameter == "frequency" else "displacement"]
        label_axis(self.plot, "bottom", parameter, self.unit)
        for item in self._scatter.values():
            item.setData([], [])
        self.table.setRowCount(0)
        self.state.setText(f"{parameter} sweep: each step appears here as it ends")

    def add_step(self, step: LiveStep) -> None:
        """Draw a judged step's points and list its regime."""
        self.steps.append(step)
        for direction, item in self._scatter.items():
            item.setData(*diagram_points(self.steps, self.unit, direction))
        row = self.table.rowCount()
        self.table.insertRow(row)
        cells = (str(step.step), "up" if step.direction > 0 else "down",
                 f"{self.unit.show(step.setting):.4g} {self.unit.unit}", step.regime,
                 str(step.points_rad.size), f"{step.held_s:.1f} s")
        for column, text in enumerate(cells):
            item = QTableWidgetItem(text)
            if column == 3:
                item.setToolTip(step.label)
            self.table.setItem(row, column, item)
        self.state.setText(f"step {step.step}: {step.regime} ({step.label})")

    def note(self, text: str) -> None:
        """A step that could not be judged, or the sweep's end."""
        self.state.setText(text)
