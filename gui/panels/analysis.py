"""Analysis: identify the current or a chosen recording, or explain it (``analyze``: the causes,
the residual before and after, the regime), on a worker thread; overlay the model."""

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
    QProgressBar,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from analysis.experiments import NAMES
from gui.decimate import min_max_decimate
from gui.plot_axes import label_axis
from gui.units import DISPLAY

if TYPE_CHECKING:
    from gui.model_overlay import ModelOverlay

EXPERIMENTS = ("as recorded", *NAMES)


class AnalysisPanel(QWidget):
    """File choice, Run, the report, and a plot of data with the model's response on top."""

    run_requested = Signal(str, str)  # path, experiment ('' = as recorded)
    explain_requested = Signal(str, str)  # the same, for the discrepancy analysis

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.path = QLineEdit()
        self.path.setPlaceholderText("recording to identify (.h5) or exchange CSV")
        self.use_current = QPushButton("Current recording")
        self.browse = QPushButton("Browse...")
        self.experiment = QComboBox()
        self.experiment.addItems(EXPERIMENTS)
        self.run = QPushButton("Identify")
        self.run.setToolTip("fit the baseline model and overlay its response")
        self.explain = QPushButton("Explain")
        self.explain.setToolTip("analyze: which cause explains where the baseline model fails")
        self.busy = QProgressBar()
        self.busy.setRange(0, 0)  # the analysis reports stages, not a fraction done
        self.busy.setVisible(False)
        self.state = QLabel("")
        self.state.setWordWrap(True)
        self.explanation = QPlainTextEdit()
        self.explanation.setReadOnly(True)
        self.explanation.setPlaceholderText("Explain shows the causes, the residual and the regime")
        self.report = QPlainTextEdit()
        self.report.setReadOnly(True)
        self.plot = pg.PlotWidget()
        self.plot.addLegend()
        label_axis(self.plot, "bottom", "time from the start", DISPLAY["time"])
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
        row.addWidget(self.explain)
        texts = QSplitter(Qt.Orientation.Horizontal)
        texts.addWidget(self.explanation)
        texts.addWidget(self.report)
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.plot)
        splitter.addWidget(texts)
        splitter.setSizes([300, 200])
        layout = QVBoxLayout(self)
        layout.addLayout(row)
        layout.addWidget(self.busy)
        layout.addWidget(self.state)
        layout.addWidget(splitter, 1)
        self.current_recording = ""
        self.overlay: ModelOverlay | None = None
        self.explained: dict | None = None  # the last analysis' JSON report
        self._verb = "identify"  # what the running (or last) request does
        self.stages: list[str] = []  # the running (or last) analysis' progress messages
        self.use_current.clicked.connect(lambda: self.path.setText(self.current_recording))
        self.browse.clicked.connect(self._browse)
        self.run.clicked.connect(lambda: self._start(self.run_requested, "identify"))
        self.explain.clicked.connect(lambda: self._start(self.explain_requested, "explain"))

    def _browse(self) -> None:
        name, _ = QFileDialog.getOpenFileName(
            self, "Recording", "", "Recordings (*.h5 *.hdf5 *.csv)"
        )
        if name:
            self.path.setText(name)

    def _start(self, request: Signal, verb: str) -> None:
        """Ask the window to identify or explain the chosen recording; busy until it answers."""
        path = self.path.text().strip() or self.current_recording
        if not path:
            self.state.setText("choose a recording first")
            return
        self.path.setText(path)
        experiment = self.experiment.currentText()
        self._show_busy(True)
        self._verb = verb
        self.stages.clear()
        self.state.setText(f"{verb}ing {path} ...")
        request.emit(path, "" if experiment == "as recorded" else experiment)

    def _show_busy(self, busy: bool) -> None:
        """One analysis at a time: the buttons wait while the worker runs."""
        self.run.setEnabled(not busy)
        self.explain.setEnabled(not busy)
        self.busy.setVisible(busy)

    def show_progress(self, text: str) -> None:
        """The running analysis' newest stage (kept: the explanation ends with them)."""
        self.stages.append(text)
        self.state.setText(text)

    def show_result(self, overlay: ModelOverlay) -> None:
        """Draw the data and the model's response; show the report."""
        self.overlay = overlay
        self._show_busy(False)
        unit = DISPLAY["angle" if overlay.quantity == "angle" else "displacement"]
        label_axis(self.plot, "left", overlay.quantity, unit)
        columns = max(200, self.plot.width())
        self.measured_curve.setData(
            *min_max_decimate(overlay.time_s, unit.show(overlay.measured), columns)
        )
        self.model_curve.setData(
            *min_max_decimate(overlay.model_time_s, unit.show(overlay.model), columns)
        )
        self.state.setText(
            f"{overlay.result.method}: rms difference data - model "
            f"{unit.show(overlay.rms_difference):.3g} {unit.unit}"
        )
        self.report.setPlainText(overlay.result.summary())

    def show_explanation(self, report: dict) -> None:
        """Show what the discrepancy analysis found (its JSON report)."""
        from gui.model_overlay import explanation_lines

        self.explained = report
        self._show_busy(False)
        lines = explanation_lines(report)
        self.explanation.setPlainText("\n".join([*lines, "", "how the analysis went:",
                                                 *self.stages]))
        self.state.setText(lines[0])

    def show_error(self, error: BaseException) -> None:
        """Identification or the analysis failed: say why, in words."""
        self._show_busy(False)
        self.state.setText(f"cannot {self._verb}: {error}")
