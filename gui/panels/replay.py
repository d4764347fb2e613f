"""Replay controls: play/pause, seek along the recording, speed."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSlider,
    QVBoxLayout,
    QWidget,
)

SPEEDS = ("0.25x", "0.5x", "1x", "2x", "4x", "10x", "max")
SLIDER_STEPS = 1000


class ReplayPanel(QGroupBox):
    """Signals: ``play_requested``, ``pause_requested``, ``seek_requested(fraction)``,
    ``speed_changed(text)``."""

    play_requested = Signal()
    pause_requested = Signal()
    seek_requested = Signal(float)
    speed_changed = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Replay", parent)
        self.play_pause = QPushButton("Play")
        self.speed = QComboBox()
        self.speed.addItems(SPEEDS)
        self.speed.setCurrentText("1x")
        self.position = QSlider(Qt.Orientation.Horizontal)
        self.position.setRange(0, SLIDER_STEPS)
        self.time = QLabel("-")
        row = QHBoxLayout()
        row.addWidget(self.play_pause)
        row.addWidget(QLabel("Speed"))
        row.addWidget(self.speed)
        layout = QVBoxLayout(self)
        layout.addLayout(row)
        layout.addWidget(self.position)
        layout.addWidget(self.time)
        self.playing = False
        self.play_pause.clicked.connect(
            lambda: (self.pause_requested if self.playing else self.play_requested).emit()
        )
        self.position.sliderReleased.connect(
            lambda: self.seek_requested.emit(self.position.value() / SLIDER_STEPS)
        )
        self.speed.currentTextChanged.connect(self.speed_changed.emit)
        self.setEnabled(False)

    def show_playing(self, playing: bool) -> None:
        self.playing = playing
        self.play_pause.setText("Pause" if playing else "Play")

    def show_position(self, position_s: float, duration_s: float, finished: bool = False) -> None:
        """Where the replay is (the slider follows unless the user holds it)."""
        self.time.setText(
            f"{position_s:.1f} s of {duration_s:.1f} s" + (" (end)" if finished else "")
        )
        if not self.position.isSliderDown() and duration_s > 0:
            self.position.setValue(round(SLIDER_STEPS * min(1.0, position_s / duration_s)))
