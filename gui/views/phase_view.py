"""Phase portrait: angular velocity against angle over the last few seconds."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from analysis.dynamics.poincare import smoothed_derivative
from gui.live_data import LiveData
from gui.plot_axes import HandZoom, fit_axes, label_axis
from gui.units import DISPLAY

MAX_POINTS = 6000


class PhasePortraitView(QWidget):
    """The trajectory (theta, theta') of the newest ``length_s`` seconds."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.length_s = QDoubleSpinBox(minimum=0.2, maximum=20.0, value=2.0, suffix=" s")
        controls = QHBoxLayout()
        controls.addWidget(QLabel("Last"))
        controls.addWidget(self.length_s)
        controls.addStretch(1)
        self.plot = pg.PlotWidget()
        self.hand_zoom = HandZoom(self.plot)
        label_axis(self.plot, "bottom", "angle", DISPLAY["angle"])
        label_axis(self.plot, "left", "angular velocity", DISPLAY["angular_velocity"])
        self.curve = self.plot.plot(pen=pg.mkPen("#6a2a9c", width=1))
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(controls)
        layout.addWidget(self.plot)

    def refresh(self, data: LiveData) -> None:
        """Redraw the newest stretch (derivative by a smoothing filter, then thinned)."""
        index, theta = data.angle.latest(int(self.length_s.value() * data.sample_rate_hz))
        if theta.size < 64 or np.any(np.diff(index) != 1):
            return
        # differentiate at about 5 kHz (impacts last milliseconds): far cheaper at 40 kHz
        stride = max(1, int(data.sample_rate_hz // 5000))
        theta = theta[::stride]
        fs = data.sample_rate_hz / stride
        window = max(15, int(fs / 200) | 1)  # about 5 ms: smooths noise, keeps impacts sharp
        if theta.size < 2 * window:
            return
        rate = smoothed_derivative(theta, fs, window_samples=window)
        step = max(1, theta.size // MAX_POINTS)
        angle, velocity = DISPLAY["angle"], DISPLAY["angular_velocity"]
        x, y = angle.show(theta[::step]), velocity.show(rate[::step])
        self.curve.setData(x, y)
        fit_axes(self.plot, x, y, angle, velocity, self.hand_zoom)
