"""Analysis: identify the current or a chosen recording on a worker thread; overlay the model."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPlainTextEdit,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from analysis.experiments import NAMES
from gui.decimate import min_max_decimate

if TYPE_CHECKING:
    from gui.model_overlay import ModelOverlay

EXPERIMENTS = ("as recorded", *NAMES)


class AnalysisPanel(QWidget):
    """File choice, Run, the report, and a plot of data with the model's response on top."""

    run_requested = Signal(str, str)  # path, experiment ('' = as recorded)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.path = QLineEdit()
        self.path.setPlaceholderText("recording to identify (.h5) or exchange CSV")
        self.use_current = QPushButton("Current recording")
        self.browse = QPushButton("Browse...")
        self.experiment = QComboBox()
        self.experiment.addItems(EXPERIMENTS)
        self.run = QPushButton("Identify")
        self.state = QLabel("")
        self.state.setWordWrap(True)
        self.report = QPlainTextEdit()
        self.report.setReadOnly(True)
        self.plot = pg.PlotWidget()
        self.plot.addLegend()
        self.plot.setLabel("bottom", "time", units="s")
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.measured_curve = self.plot.plot(pen=pg.mkPen("#1f4e9c"), name="measured")
        self.model_curve = self.plot.plot(pen=pg.mkPen("#d06000", width=2), name="model")
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(self.use_current)
        row.addWidget(self.browse)
        row.addWidget(QLabel("as"))
        row.addWidget(self.experiment)
        row.addWidget(self.run)
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.plot)
        splitter.addWidget(self.report)
        splitter.setSizes([300, 150])
        layout = QVBoxLayout(self)
        layout.addLayout(row)
        layout.addWidget(self.state)
        layout.addWidget(splitter, 1)
        self.current_recording = ""
        self.overlay: ModelOverlay | None = None
        self.use_current.clicked.connect(lambda: self.path.setText(self.current_recording))
        self.browse.clicked.connect(self._browse)
        self.run.clicked.connect(self._run)

    def _browse(self) -> None:
        name, _ = QFileDialog.getOpenFileName(
            self, "Recording", "", "Recordings (*.h5 *.hdf5 *.csv)"
        )
        if name:
            self.path.setText(name)

    def _run(self) -> None:
        path = self.path.text().strip() or self.current_recording
        if not path:
            self.state.setText("choose a recording first")
            return
        self.path.setText(path)
        experiment = self.experiment.currentText()
        self.run.setEnabled(False)
        self.state.setText(f"identifying {path} ...")
        self.run_requested.emit(path, "" if experiment == "as recorded" else experiment)

    def show_result(self, overlay: ModelOverlay) -> None:
        """Draw the data and the model's response; show the report."""
        self.overlay = overlay
        self.run.setEnabled(True)
        unit = "rad" if overlay.quantity == "angle" else "m"
        self.plot.setLabel("left", overlay.quantity, units=unit)
        columns = max(200, self.plot.width())
        self.measured_curve.setData(*min_max_decimate(overlay.time_s, overlay.measured, columns))
        self.model_curve.setData(*min_max_decimate(overlay.model_time_s, overlay.model, columns))
        self.state.setText(
            f"{overlay.result.method}: rms difference data - model "
            f"{overlay.rms_difference:.3g} {unit}"
        )
        self.report.setPlainText(overlay.result.summary())

    def show_error(self, error: BaseException) -> None:
        """Identification failed: say why, in words."""
        self.run.setEnabled(True)
        self.state.setText(f"cannot identify: {error}")
