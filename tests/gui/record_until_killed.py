"""The whole GUI application, offscreen, recording the virtual rig until it is killed.

``python -m tests.gui.record_until_killed FILE.h5 SETTINGS.ini``: opens the main window,
the virtual rig and a recording to FILE.h5 through the window's own actions, then prints
``taken N`` every 50 ms (N: the samples the acquisition engine has taken in so far) until
something kills it (``tests/gui/test_killed.py``).
"""

from __future__ import annotations

import os
import sys
import time

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtWidgets import QApplication

RATE_HZ = 20_000.0


def main(path: str, settings_file: str) -> None:
    from gui.app import MainWindow
    from gui.settings import AppSettings
    from gui.worker import LiveSession

    app = QApplication([])
    window = MainWindow(AppSettings(settings_file))
    window.show()
    window.open_virtual_rig(RATE_HZ)
    while not isinstance(window.session, LiveSession):
        app.processEvents()
        time.sleep(0.01)
    window.start_recording(path, "killed GUI")
    while window.session.recording is None:
        app.processEvents()
        time.sleep(0.01)
    print("recording", flush=True)
    while True:  # the window's own loop, as a user has it, until the kill
        deadline = time.monotonic() + 0.05
        while time.monotonic() < deadline:
            app.processEvents()
            time.sleep(0.005)
        print(f"taken {window.session.engine.aligned_end_index or 0}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
