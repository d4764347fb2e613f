"""Analysis: identify the current or a chosen recording, or explain it (``analyze``: the causes,
the residual before and after, the regime), on a worker thread; overlay the model.  A sweep
recording is explained as a sweep: its measured diagram, its per-step table and the sweep
report's figures."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from analysis.experiments import NAMES
from gui.decimate import min_max_decimate
from gui.plot_axes import label_axis
from gui.units import DISPLAY, DisplayUnit

if TYPE_CHECKING:
    from gui.model_overlay import Explanation, ModelOverlay
    from gui.sweep_explanation import SweepExplanation

EXPERIMENTS = ("as recorded", *NAMES)
CURVE_COLOURS = ("#1f4e9c", "#d06000", "#1a8a3a")  # measured, model, extended model
MODEL_SHIFT = 0.06  # a model's diagram points sit this fraction of a step beside the measured


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
        label_axis(self.plot, "bottom", "time from the start", DISPLAY["time"])
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.measured_curve = self.plot.plot(pen=pg.mkPen(CURVE_COLOURS[0]))
        self.model_curve = self.plot.plot(pen=pg.mkPen(CURVE_COLOURS[1], width=2))
        self.extended_curve = self.plot.plot(
            pen=pg.mkPen(CURVE_COLOURS[2], width=2, style=Qt.PenStyle.DashLine)
        )
        self.extended_curve.setVisible(False)
        self.diagram_points = pg.ScatterPlotItem(size=5, pen=None,
                                                 brush=pg.mkBrush(CURVE_COLOURS[0]))
        self.plot.addItem(self.diagram_points)
        self.model_points = [pg.ScatterPlotItem(size=6, symbol="x", pen=pg.mkPen(colour),
                                                brush=None) for colour in CURVE_COLOURS[1:]]
        for item in self.model_points:
            self.plot.addItem(item)
        self.figures = QWidget()  # a sweep report's figures, as the report draws them
        self.figures_layout = QVBoxLayout(self.figures)
        self.figure_labels: list[QLabel] = []
        figures_scroll = QScrollArea()
        figures_scroll.setWidget(self.figures)
        figures_scroll.setWidgetResizable(True)
        self.key: list[str] = []  # the curves drawn, named in colour above the plot
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
        texts.addWidget(figures_scroll)
        texts.setSizes([300, 300, 0])
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

    def _draw(self, *curves: tuple[str, np.ndarray, np.ndarray | None],
              unit: DisplayUnit) -> None:
        """The measured, model and extended curves (name, time, values; None hides one) in
        display units, decimated to the plot's width, named in their colours above the plot
        (a legend inside would sit on the data)."""
        self.plot.enableAutoRange()  # a new result is shown whole, whatever the last zoom
        self.diagram_points.setData([], [])
        for item in self.model_points:
            item.setData([], [])
        label_axis(self.plot, "bottom", "time from the start", DISPLAY["time"])
        self.key = []
        key_html = []
        items = (self.measured_curve, self.model_curve, self.extended_curve)
        for item, colour, (name, t, y) in zip(items, CURVE_COLOURS, curves, strict=True):
            if y is None:
                item.setData([], [])
                item.setVisible(False)
                continue
            shown = np.isfinite(y)
            item.setData(*min_max_decimate(t[shown], unit.show(y[shown]),
                                           max(200, self.plot.width())))
            item.setVisible(True)
            self.key.append(name)
            key_html.append(f'<span style="color:{colour}">&#9472;&#9472; {html.escape(name)}'
                            "</span>")
        self.plot.setTitle("&nbsp;&nbsp;&nbsp;".join(key_html), size="9pt")

    def show_result(self, overlay: ModelOverlay) -> None:
        """Draw the data and the model's response; show the report."""
        self.overlay = overlay
        self._show_busy(False)
        unit = DISPLAY["angle" if overlay.quantity == "angle" else "displacement"]
        label_axis(self.plot, "left", overlay.quantity, unit)
        self._draw(("measured", overlay.time_s, overlay.measured),
                   ("identified model", overlay.model_time_s, overlay.model),
                   ("", overlay.time_s, None), unit=unit)
        self.state.setText(
            f"{overlay.result.method}: rms difference data - model "
            f"{unit.show(overlay.rms_difference):.3g} {unit.unit}"
        )
        self.report.setPlainText(overlay.result.summary())

    def show_explanation(self, explanation: Explanation) -> None:
        """Show what the discrepancy analysis found, and draw the angle it fitted with the
        baseline's and the extended model's responses."""
        from gui.model_overlay import explanation_lines

        report = self.explained = explanation.report
        self._show_busy(False)
        unit = DISPLAY["angle"]
        label_axis(self.plot, "left", "angle", unit)
        t = explanation.time_s
        self._draw(("measured", t, explanation.measured_rad),
                   ("baseline model", t, explanation.baseline_rad),
                   (explanation.extended_label, t, explanation.extended_rad), unit=unit)
        lines = explanation_lines(report)
        self.explanation.setPlainText("\n".join([*lines, "", "how the analysis went:",
                                                 *self.stages]))
        self.state.setText(lines[0])

    def show_sweep_explanation(self, explanation: SweepExplanation) -> None:
        """Show what the analysis of a sweep found: the measured diagram (the points at drive
        phase 0 of every settled period, step by step, the way down shifted right), the
        per-step table, and the report's figures."""
        from gui.live_sweep import diagram_points, step_spacing
        from gui.sweep_explanation import step_table, sweep_lines

        self.explained = explanation.report
        self._show_busy(False)
        self._draw(("", np.zeros(0), None), ("", np.zeros(0), None), ("", np.zeros(0), None),
                   unit=DISPLAY["angle"])
        unit = DISPLAY["frequency" if explanation.parameter == "frequency" else "displacement"]
        label_axis(self.plot, "bottom", explanation.parameter, unit)
        label_axis(self.plot, "left", "angle at drive phase 0", DISPLAY["angle"])
        self.diagram_points.setData(*diagram_points(explanation.steps, unit))
        self.key = ["measured"]
        key_html = [f'<span style="color:{CURVE_COLOURS[0]}">&#9679; measured</span>']
        spacing = step_spacing([unit.show(s.setting) for s in explanation.steps])
        for number, (item, colour, (name, steps)) in enumerate(
                zip(self.model_points, CURVE_COLOURS[1:], explanation.models, strict=False)):
            x, y = diagram_points(steps, unit)
            item.setData(x + MODEL_SHIFT * spacing * (number + 1), y)
            self.key.append(name)
            key_html.append(f'<span style="color:{colour}">&#215; {html.escape(name)}</span>')
        self.plot.setTitle("&nbsp;&nbsp;&nbsp;".join(key_html)
                           + "&nbsp;&nbsp;(angle at drive phase 0; the way down shifted right)",
                           size="9pt")
        lines = sweep_lines(explanation)
        self.explanation.setPlainText("\n".join([*lines, "", "how the analysis went:",
                                                 *self.stages]))
        self.report.setPlainText("\n".join(step_table(explanation)))
        self._show_figures(explanation.figures)
        self.state.setText(lines[0])

    def _show_figures(self, figures: tuple[tuple[str, bytes], ...]) -> None:
        for label in self.figure_labels:
            label.deleteLater()
        self.figure_labels = []
        for name, png in figures:
            pixmap = QPixmap()
            pixmap.loadFromData(png, "PNG")
            label = QLabel()
            label.setPixmap(pixmap)
            label.setToolTip(name)
            self.figures_layout.addWidget(label)
            self.figure_labels.append(label)

    def show_error(self, error: BaseException) -> None:
        """Identification or the analysis failed: say why, in words."""
        self._show_busy(False)
        self.state.setText(f"cannot {self._verb}: {error}")

