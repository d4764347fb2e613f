"""Shaker control: frequency, amplitude (also as beta = A/L), ramp rate, enable, within limits.

Values are checked against the rig file's limits before anything is sent: a refused
value shows a message here and never reaches the amplifier.
"""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QWidget,
)

from analysis import quantities as q
from drivers.amplifier_registers import (
    DEVICE_MAX_AMPLITUDE_UM,
    DEVICE_MAX_FREQUENCY_MHZ,
    DEVICE_MAX_RAMP_RATE_UM_S,
)
from drivers.interfaces import LimitError
from gui.units import DISPLAY

MM = DISPLAY["displacement"]
MM_S = DISPLAY["speed"]


class ShakerPanel(QGroupBox):
    """Drive settings; ``apply_requested(frequency_hz, amplitude_m, enabled, ramp_m_s)``."""

    apply_requested = Signal(float, float, bool, float)
    clear_faults_requested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Shaker", parent)
        self.L_m = 0.046
        self.limits = None
        # the boxes accept up to the amplifier's own range; the lab's limits are checked on Apply
        self.frequency = QDoubleSpinBox(decimals=3, maximum=DEVICE_MAX_FREQUENCY_MHZ / 1000.0)
        self.frequency.setSuffix(" Hz")
        self.frequency.setValue(10.0)
        self.amplitude_mm = QDoubleSpinBox(decimals=3, maximum=DEVICE_MAX_AMPLITUDE_UM / 1000.0)
        self.amplitude_mm.setSuffix(f" {MM.unit}")
        self.amplitude_mm.setSingleStep(0.1)
        self.beta = QDoubleSpinBox(decimals=4, maximum=100.0, singleStep=0.005)
        self.beta.setToolTip("beta = A / L, the nondimensional drive amplitude (docs/MODEL.md)")
        self.ramp = QDoubleSpinBox(decimals=3, maximum=DEVICE_MAX_RAMP_RATE_UM_S / 1000.0)
        self.ramp.setSuffix(f" {MM_S.unit}")
        self.ramp.setValue(5.0)
        self.enable = QCheckBox("drive on")
        self.apply = QPushButton("Apply")
        self.clear_faults = QPushButton("Clear faults")
        self.clear_faults.setToolTip("clear latched amplifier faults whose cause is gone")
        self.limits_label = QLabel("")
        self.limits_label.setWordWrap(True)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b00000")
        form = QFormLayout(self)
        form.addRow("Frequency", self.frequency)
        form.addRow("Amplitude", self.amplitude_mm)
        form.addRow("beta = A/L", self.beta)
        form.addRow("Ramp rate", self.ramp)
        form.addRow(self.enable, self.apply)
        form.addRow(self.clear_faults)
        form.addRow(self.limits_label)
        form.addRow(self.message)
        self.amplitude_mm.valueChanged.connect(self._amplitude_changed)
        self.beta.valueChanged.connect(self._beta_changed)
        self.apply.clicked.connect(self._apply)
        self.clear_faults.clicked.connect(self.clear_faults_requested.emit)
        self._syncing = False
        self.setEnabled(False)

    def configure(self, limits, L_m: float) -> None:
        """Show the configured limits (drivers.limits.ShakerLimits) and the rig's L."""
        self.limits = limits
        self.L_m = L_m
        self.limits_label.setText(
            f"limits: {limits.min_frequency_hz:g}-{limits.max_frequency_hz:g} Hz, "
            f"up to {MM.show(limits.max_amplitude_m):g} {MM.unit} "
            f"(beta {limits.max_amplitude_m / L_m:.3g}), ramp "
            f"{MM_S.show(limits.min_ramp_rate_m_s):g}-{MM_S.show(limits.max_ramp_rate_m_s):g} "
            f"{MM_S.unit}"
        )
        self._amplitude_changed(self.amplitude_mm.value())

    def _amplitude_changed(self, millimetres: float) -> None:
        if self._syncing:
            return
        self._syncing = True
        self.beta.setValue(MM.si(millimetres) / self.L_m)
        self._syncing = False

    def _beta_changed(self, beta: float) -> None:
        if self._syncing:
            return
        self._syncing = True
        self.amplitude_mm.setValue(MM.show(beta * self.L_m))
        self._syncing = False

    def values(self) -> tuple[float, float, bool, float]:
        """(frequency_hz, amplitude_m, enabled, ramp_rate_m_s) as entered."""
        return (
            self.frequency.value(),
            MM.si(self.amplitude_mm.value()),
            self.enable.isChecked(),
            MM_S.si(self.ramp.value()),
        )

    def check(self) -> str:
        """'' when the entered values are within the limits, else the refusal in words."""
        if self.limits is None:
            return "not connected to a shaker"
        frequency_hz, amplitude_m, _, ramp = self.values()
        lim = self.limits
        try:
            lim.check(
                q.frequency_hz, frequency_hz, lim.min_frequency_hz, lim.max_frequency_hz, "Hz"
            )
            lim.check(q.amplitude_m, amplitude_m, 0.0, lim.max_amplitude_m, "m")
            lim.check("ramp_rate_m_s", ramp, lim.min_ramp_rate_m_s, lim.max_ramp_rate_m_s, "m/s")
        except LimitError as error:
            return str(error)
        return ""

    def _apply(self) -> None:
        refusal = self.check()
        if refusal:
            self.show_message(f"Refused: {refusal}")
            return
        self.show_message("")
        self.apply_requested.emit(*self.values())

    def show_message(self, text: str) -> None:
        """A refusal or a device error, in words (empty to clear)."""
        self.message.setText(text)
