"""``impact-rig gui``: help, the screenshot option on the virtual rig, settings kept."""

from __future__ import annotations

import os
import subprocess
import sys

from PySide6.QtGui import QImage

from gui.app import MainWindow
from gui.settings import AppSettings


def run_gui(args: list[str], settings_file, timeout_s: float = 120):
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", IMPACT_RIG_GUI_SETTINGS=str(settings_file))
    return subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from rig.cli import main; sys.exit(main())",
            "gui",
            *args,
        ],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env=env,
    )


def test_help_teaches_the_options(tmp_path):
    done = run_gui(["--help"], tmp_path / "s.ini")
    assert done.returncode == 0
    for option in ("--sim", "--config", "--replay", "--screenshot", "--after"):
        assert option in done.stdout


def test_screenshot_of_the_live_virtual_rig(tmp_path):
    png = tmp_path / "shot.png"
    done = run_gui(
        ["--sim", "--view", "time", "--screenshot", str(png), "--after", "4"], tmp_path / "s.ini"
    )
    assert done.returncode == 0, done.stderr
    image = QImage(str(png))
    assert not image.isNull() and image.width() >= 800 and image.height() >= 500
    # the plots are not blank: the angle trace puts dark-blue pixels on the white plot
    blue = sum(
        1
        for x in range(0, image.width(), 3)
        for y in range(0, image.height(), 3)
        if image.pixelColor(x, y).blue() > 120 and image.pixelColor(x, y).red() < 80
    )
    assert blue > 50


def test_missing_replay_file_is_a_clear_error(tmp_path):
    done = run_gui(["--replay", str(tmp_path / "nope.h5")], tmp_path / "s.ini")
    assert done.returncode == 2
    assert "nope.h5: file not found" in done.stderr


def test_settings_persist_between_runs(qapp, tmp_path):
    path = str(tmp_path / "gui.ini")
    first = MainWindow(AppSettings(path))
    first.shaker_panel.frequency.setValue(12.5)
    first.shaker_panel.amplitude_mm.setValue(2.25)
    first.spectrum_view.window.setCurrentText("blackman")
    first.recording_panel.path.setText(str(tmp_path / "mine.h5"))
    first.show_view("poincare")
    first.shutdown()
    first.close()
    second = MainWindow(AppSettings(path))
    try:
        assert second.shaker_panel.frequency.value() == 12.5
        assert second.shaker_panel.amplitude_mm.value() == 2.25
        assert second.spectrum_view.window.currentText() == "blackman"
        assert second.recording_panel.path.text() == str(tmp_path / "mine.h5")
        assert second.tabs.currentWidget() is second.poincare_view
    finally:
        second.shutdown()
        second.close()


def test_unreachable_real_rig_is_reported_in_words(qapp, tmp_path):
    from rig.config import default_config_path
    from tests.gui.conftest import wait_until

    text = default_config_path().read_text()
    text = text.replace('kind = "virtual"', 'kind = "real"')
    text = text.replace('port = "sim"', f'port = "{tmp_path / "no-such-port"}"')
    rig_file = tmp_path / "lab.toml"
    rig_file.write_text(text)
    window = MainWindow(AppSettings(str(tmp_path / "gui.ini")))
    try:
        window.open_rig_file(str(rig_file))
        wait_until(qapp, lambda: window.last_error, 30, "the connection attempt to fail")
        state = window.connection_panel.state.text()
        assert state.startswith("cannot connect:") and "no-such-port" in state
        assert window.session is None and window.connection_panel.connect_button.isEnabled()
    finally:
        window.shutdown()
        window.close()
