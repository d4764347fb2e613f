"""Recording: file name, operator notes, start/stop, elapsed time and file size; sweeps."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from gui.units import DISPLAY, DisplayUnit
from rig.procedures import SweepPlan


def _swept_and_fixed(parameter: str) -> tuple[DisplayUnit, DisplayUnit]:
    """The display units of a sweep's swept values and of the one held fixed."""
    frequency, amplitude = DISPLAY["frequency"], DISPLAY["displacement"]
    return (frequency, amplitude) if parameter == "frequency" else (amplitude, frequency)


def human_size(size_bytes: int) -> str:
    """'812 kB', '3.4 MB'."""
    if size_bytes < 1e6:
        return f"{size_bytes / 1e3:.0f} kB"
    return f"{size_bytes / 1e6:.1f} MB"


class RecordingPanel(QGroupBox):
    """Start/stop a recording; ``start_requested(path, notes)``, ``stop_requested()``."""

    start_requested = Signal(str, str)
    stop_requested = Signal()
    sweep_requested = Signal(object, str, str)  # SweepPlan, path, notes
    sweep_cancel_requested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Recording", parent)
        self.path = QLineEdit("run.h5")
        self.browse = QPushButton("...")
        self.notes = QPlainTextEdit()
        self.notes.setPlaceholderText("operator notes (kept in the file)")
        self.notes.setMaximumHeight(60)
        self.start_stop = QPushButton("Start recording")
        self.elapsed = QLabel("-")
        self.size = QLabel("-")
        self.message = QLabel("")
        self.message.setWordWrap(True)
        file_row = QHBoxLayout()
        file_row.addWidget(self.path, 1)
        file_row.addWidget(self.browse)
        form = QFormLayout()
        form.addRow("File", file_row)
        form.addRow("Notes", self.notes)
        progress_row = QHBoxLayout()
        progress_row.addWidget(self.elapsed)
        progress_row.addWidget(QLabel("File size"))
        progress_row.addWidget(self.size, 1)
        form.addRow(self.start_stop)
        form.addRow("Elapsed", progress_row)
        # sweep runner
        self.sweep_parameter = QComboBox()
        self.sweep_parameter.addItems(["frequency", "amplitude"])
        self.sweep_from = QDoubleSpinBox(decimals=3, maximum=1000.0, value=8.0)
        self.sweep_to = QDoubleSpinBox(decimals=3, maximum=1000.0, value=12.0)
        self.sweep_steps = QSpinBox(minimum=1, maximum=200, value=5)
        self.sweep_fixed = QDoubleSpinBox(decimals=3, maximum=1000.0, value=1.0)
        self.sweep_fixed.setToolTip("amplitude in mm for a frequency sweep, frequency in Hz else")
        self.sweep_settle = QDoubleSpinBox(decimals=1, maximum=600.0, value=3.0, suffix=" s")
        self.sweep_dwell = QDoubleSpinBox(decimals=1, minimum=0.1, maximum=3600.0, value=5.0)
        self.sweep_dwell.setSuffix(" s")
        self.sweep_down = QCheckBox("and back down")
        self.sweep_down.setChecked(True)
        self.sweep_run = QPushButton("Run sweep")
        self.sweep_progress = QProgressBar()
        self.sweep_text = QLabel("")
        self.sweep_text.setWordWrap(True)
        sweep = QGroupBox("Sweep")
        sweep_grid = QGridLayout(sweep)
        for row, pairs in enumerate((
            (("Sweep", self.sweep_parameter), ("Steps", self.sweep_steps)),
            (("From", self.sweep_from), ("To", self.sweep_to)),
            (("Fixed", self.sweep_fixed),),
            (("Settle", self.sweep_settle), ("Dwell", self.sweep_dwell)),
        )):
            for pair, (title, widget) in enumerate(pairs):
                sweep_grid.addWidget(QLabel(title), row, 2 * pair)
                sweep_grid.addWidget(widget, row, 2 * pair + 1)
        sweep_grid.addWidget(self.sweep_down, 4, 0, 1, 2)
        sweep_grid.addWidget(self.sweep_run, 4, 2, 1, 2)
        sweep_grid.addWidget(self.sweep_progress, 5, 0, 1, 4)
        sweep_grid.addWidget(self.sweep_text, 6, 0, 1, 4)
        self.sweep_parameter.currentTextChanged.connect(self._label_sweep_units)
        self._label_sweep_units(self.sweep_parameter.currentText())
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self.message)
        layout.addWidget(sweep)
        self.recording = False
        self.sweeping = False
        self.browse.clicked.connect(self._browse)
        self.start_stop.clicked.connect(self._start_stop)
        self.sweep_run.clicked.connect(self._sweep_clicked)
        self.setEnabled(False)

    def _label_sweep_units(self, parameter: str) -> None:
        """The swept values in Hz or mm, the fixed one in the other."""
        swept, fixed = _swept_and_fixed(parameter)
        self.sweep_from.setSuffix(f" {swept.unit}")
        self.sweep_to.setSuffix(f" {swept.unit}")
        self.sweep_fixed.setSuffix(f" {fixed.unit}")

    def _browse(self) -> None:
        name, _ = QFileDialog.getSaveFileName(self, "Record to", self.path.text(), "*.h5")
        if name:
            self.path.setText(name)

    def _start_stop(self) -> None:
        if self.recording:
            self.stop_requested.emit()
        else:
            self.start_requested.emit(self.path.text().strip(), self.notes.toPlainText())

    def sweep_plan(self) -> SweepPlan:
        """The sweep as entered (ValueError when it makes no sense)."""
        values = np.linspace(
            self.sweep_from.value(), self.sweep_to.value(), self.sweep_steps.value()
        )
        swept, fixed = _swept_and_fixed(self.sweep_parameter.currentText())
        return SweepPlan(
            parameter=self.sweep_parameter.currentText(),
            values=tuple(swept.si(float(v)) for v in values),
            fixed=fixed.si(self.sweep_fixed.value()),
            settle_s=self.sweep_settle.value(),
            dwell_s=self.sweep_dwell.value(),
            down=self.sweep_down.isChecked(),
        )

    def _sweep_clicked(self) -> None:
        if self.sweeping:
            self.sweep_cancel_requested.emit()
            return
        try:
            plan = self.sweep_plan()
        except ValueError as error:
            self.sweep_text.setText(f"Refused: {error}")
            return
        self.sweep_requested.emit(plan, self.path.text().strip(), self.notes.toPlainText())

    def show_recording(self, recording: bool, text: str = "") -> None:
        """Switch the button between start and stop and show a message."""
        self.recording = recording
        self.start_stop.setText("Stop recording" if recording else "Start recording")
        self.path.setEnabled(not recording)
        self.sweep_run.setEnabled(not recording or self.sweeping)
        if text:
            self.message.setText(text)

    def show_progress(self, elapsed_s: float, size_bytes: int) -> None:
        """Elapsed time and file size of the running recording."""
        minutes, seconds = divmod(int(elapsed_s), 60)
        self.elapsed.setText(f"{minutes:d}:{seconds:02d}")
        self.size.setText(human_size(size_bytes))

    def show_sweep(self, running: bool, done: int, total: int, text: str) -> None:
        """Progress of a sweep."""
        self.sweeping = running
        self.sweep_run.setText("Cancel sweep" if running else "Run sweep")
        self.sweep_progress.setMaximum(max(total, 1))
        self.sweep_progress.setValue(done)
        self.sweep_text.setText(text)
        self.start_stop.setEnabled(not running)
