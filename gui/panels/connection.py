"""Where the data comes from: the virtual rig, a real rig from its TOML file, or a recording."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

VIRTUAL, RIG_FILE, RECORDING = "virtual rig", "rig file (TOML)", "recording (replay)"
SOURCES = (VIRTUAL, RIG_FILE, RECORDING)


class ConnectionPanel(QGroupBox):
    """Choose a source and connect; ``connect_requested(kind, path)`` asks the window to open it."""

    connect_requested = Signal(str, str)
    disconnect_requested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Connection", parent)
        self.source = QComboBox()
        self.source.addItems(SOURCES)
        self.path = QLineEdit()
        self.path.setPlaceholderText("file for a real rig or a replay")
        self.browse = QPushButton("Browse...")
        self.connect_button = QPushButton("Connect")
        self.disconnect_button = QPushButton("Disconnect")
        self.disconnect_button.setEnabled(False)
        self.state = QLabel("not connected")
        self.state.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(self.browse)
        buttons = QHBoxLayout()
        buttons.addWidget(self.connect_button)
        buttons.addWidget(self.disconnect_button)
        layout = QVBoxLayout(self)
        layout.addWidget(self.source)
        layout.addLayout(row)
        layout.addLayout(buttons)
        layout.addWidget(self.state)
        self.source.currentTextChanged.connect(self._source_changed)
        self.browse.clicked.connect(self._browse)
        self.connect_button.clicked.connect(
            lambda: self.connect_requested.emit(self.source.currentText(), self.path.text().strip())
        )
        self.disconnect_button.clicked.connect(self.disconnect_requested.emit)
        self._source_changed(self.source.currentText())

    def _source_changed(self, kind: str) -> None:
        needs_file = kind != VIRTUAL
        self.path.setEnabled(needs_file)
        self.browse.setEnabled(needs_file)

    def _browse(self) -> None:
        if self.source.currentText() == RIG_FILE:
            name, _ = QFileDialog.getOpenFileName(self, "Rig file", "", "Rig files (*.toml)")
        else:
            name, _ = QFileDialog.getOpenFileName(self, "Recording", "", "Recordings (*.h5 *.hdf5)")
        if name:
            self.path.setText(name)

    def show_state(self, text: str, connected: bool) -> None:
        """Show what is connected (or why not) and enable the right buttons."""
        self.state.setText(text)
        self.connect_button.setEnabled(not connected)
        self.disconnect_button.setEnabled(connected)
        self.source.setEnabled(not connected)
