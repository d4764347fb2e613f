"""GUI tests run on a real Qt event loop, offscreen, with settings in a temporary file."""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
# never touch the user's settings: every test session gets its own INI file
os.environ.setdefault(
    "IMPACT_RIG_GUI_SETTINGS",
    os.path.join(tempfile.mkdtemp(prefix="impact-rig-gui-"), "settings.ini"),
)

import pytest
from PySide6.QtWidgets import QApplication


def wait_until(
    app: QApplication, condition: Callable[[], object], timeout_s: float, what: str
) -> None:
    """Run the event loop until ``condition()`` is true; fail naming ``what`` after the timeout."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout_s} s waiting for {what}")
        app.processEvents()
        time.sleep(0.01)


def run_events(app: QApplication, seconds: float) -> None:
    """Let the event loop run for ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        app.processEvents()
        time.sleep(0.01)


@pytest.fixture
def open_window(qapp, tmp_path):
    """Open the main window at a given size (its settings in this test's own file); every
    window opened is shut down after the test."""
    from gui.app import MainWindow
    from gui.settings import AppSettings

    opened = []

    def open_at(width: int, height: int):
        window = MainWindow(AppSettings(str(tmp_path / "gui.ini")))
        window.resize(width, height)
        window.show()
        opened.append(window)
        return window

    yield open_at
    for window in opened:
        window.shutdown()
        window.close()
