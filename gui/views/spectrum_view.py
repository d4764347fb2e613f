"""Amplitude spectrum of the angle, peaks labelled as multiples of the drive frequency.

A period-2 response shows a line at ``1/2 f``, impacts show ``2 f``, ``3 f`` ...: the
labels make sub- and superharmonics readable at a glance.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QVBoxLayout,
    QWidget,
)

from analysis.dynamics.spectrum import Spectrum, amplitude_spectrum
from gui.live_data import LiveData
from gui.plot_axes import label_axis
from gui.units import DISPLAY

WINDOWS = ("hann", "blackman", "flattop", "boxcar")
MAX_SPECTRUM_SAMPLES = 1 << 19
MAX_LABELS = 12


class SpectrumView(QWidget):
    """Windowed spectrum of the last seconds of the angle, log or linear scale, peak labels."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.window = QComboBox()
        self.window.addItems(WINDOWS)
        self.length_s = QDoubleSpinBox(minimum=1.0, maximum=30.0, value=8.0, suffix=" s")
        self.length_s.setToolTip("length of the analysed stretch (longer: finer lines)")
        self.log_scale = QCheckBox("log scale (dB)")
        self.log_scale.setChecked(True)
        self.max_frequency = QDoubleSpinBox(minimum=1.0, maximum=20000.0, value=60.0, suffix=" Hz")
        controls = QHBoxLayout()
        for label, widget in (
            ("Window", self.window),
            ("Length", self.length_s),
            ("Up to", self.max_frequency),
        ):
            controls.addWidget(QLabel(label))
            controls.addWidget(widget)
        controls.addWidget(self.log_scale)
        controls.addStretch(1)
        self.plot = pg.PlotWidget()
        label_axis(self.plot, "bottom", "frequency", DISPLAY["frequency"])
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.curve = self.plot.plot(pen=pg.mkPen("#1f4e9c", width=1))
        self.labels = [pg.TextItem(color="#a02020", anchor=(0.5, 1.0)) for _ in range(MAX_LABELS)]
        for item in self.labels:
            self.plot.addItem(item)
        self.drive_line = pg.InfiniteLine(
            angle=90, pen=pg.mkPen("#999999", style=Qt.PenStyle.DashLine)
        )
        self.plot.addItem(self.drive_line)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(controls)
        layout.addWidget(self.plot)
        self.spectrum: Spectrum | None = None

    def snapshot(self, data: LiveData) -> tuple | None:
        """What a spectrum needs, copied on the GUI thread (None: too short or a gap)."""
        n = min(int(self.length_s.value() * data.sample_rate_hz), MAX_SPECTRUM_SAMPLES)
        index, angle = data.angle.latest(n)
        if angle.size < 64 or np.any(np.diff(index) != 1):
            return None  # a spectrum across a gap would invent samples
        return angle, data.sample_rate_hz, data.drive_frequency_hz(), self.window.currentText()

    @staticmethod
    def compute(snapshot: tuple) -> Spectrum:
        """The spectrum of a snapshot (pure: runs on a worker thread)."""
        angle, fs, drive, window = snapshot
        return amplitude_spectrum(angle, fs, drive_frequency_hz=drive, window=window)

    def refresh(self, data: LiveData) -> None:
        """Recompute the spectrum of the newest ``length_s`` seconds and redraw it (blocking)."""
        snapshot = self.snapshot(data)
        if snapshot is not None:
            self.show(self.compute(snapshot))

    def show(self, spectrum: Spectrum) -> None:
        """Draw a computed spectrum with its peak labels."""
        drive = spectrum.drive_frequency_hz
        self.spectrum = spectrum
        keep = spectrum.frequency_hz <= self.max_frequency.value()
        f = spectrum.frequency_hz[keep]
        log = self.log_scale.isChecked()
        angle = DISPLAY["angle"]
        y = spectrum.amplitude_db[keep] if log else angle.show(spectrum.amplitude[keep])
        label_axis(self.plot, "left", "amplitude (dB re the largest)" if log else
                   "amplitude", None if log else angle)
        self.curve.setData(f, y)
        self.drive_line.setVisible(drive is not None)
        if drive is not None:
            self.drive_line.setValue(drive)
        top_db = 20 * np.log10(max(float(np.max(spectrum.amplitude)), 1e-300))
        shown = [p for p in spectrum.peaks if p.frequency_hz <= self.max_frequency.value()]
        for item, peak in zip(self.labels, shown[:MAX_LABELS], strict=False):
            height = (
                (20 * np.log10(max(peak.amplitude, 1e-300)) - top_db)
                if log
                else angle.show(peak.amplitude)
            )
            item.setText(peak.label)
            item.setPos(peak.frequency_hz, height)
            item.setVisible(True)
        for item in self.labels[len(shown[:MAX_LABELS]) :]:
            item.setVisible(False)
