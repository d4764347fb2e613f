"""The screenshots of README.md and docs/guide.md (``impact-rig gui --screenshots DIR``), taken
by the same code on a quicker plan: every picture is drawn on (not one colour), carries what
made it, and shows the view and panels it is meant to, with data in them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QRect
from PySide6.QtGui import QImage

from gui.screenshots import SHOTS, ScreenshotPlan, take_screenshots
from gui.worker import LiveSession, ReplaySession
from rig.cli import main

# a stage's hang bound, under the test's own 300 s: on a fresh clone the virtual rig's first
# open compiles the integrator, which took over 120 s on CI's 2 cores under load
QUICK = ScreenshotPlan(live_s=2.0, view_s=0.6, replay_s=1.0, decay_s=4.0, timeout_s=240.0)


def pixels(image: QImage, region: QRect) -> np.ndarray:
    """The RGB pixels of ``region`` of ``image`` as an (h, w, 3) array."""
    part = image.copy(region).convertToFormat(QImage.Format.Format_RGB888)
    rows = np.frombuffer(part.constBits(), np.uint8).reshape(part.height(), part.bytesPerLine())
    # a copy: the array must not outlive the image whose memory it views
    return rows[:, : 3 * part.width()].reshape(part.height(), part.width(), 3).copy()


def assert_drawn_on(image: QImage, region: QRect, what: str) -> None:
    """Not blank: many colours, and no one colour covers nearly all of ``region``."""
    rgb = pixels(image, region).reshape(-1, 3).astype(np.uint32)
    _, counts = np.unique(rgb[:, 0] << 16 | rgb[:, 1] << 8 | rgb[:, 2], return_counts=True)
    assert counts.size > 20, (what, counts.size)
    assert counts.max() < 0.97 * counts.sum(), (what, counts.max() / counts.sum())
    assert rgb.std() > 10, (what, rgb.std())


def region_of(widget, window) -> QRect:
    """Where ``widget`` lies in a grab of ``window``."""
    return QRect(widget.mapTo(window, QPoint(0, 0)), widget.size())


def data_size(curve) -> int:
    x, _ = curve.getData()
    return 0 if x is None else x.size


def check_time_traces(window) -> None:
    view = window.time_view
    assert isinstance(window.session, LiveSession)
    assert data_size(view.angle_curve) > 100 and data_size(view.table_curve) > 100
    assert view.angle_plot.getAxis("left").labelText == "angle (deg)"
    assert view.table_plot.getAxis("left").labelText == "table (mm)"
    assert window.drive_label.text().startswith("drive: 10.000 Hz")
    assert window.recording_panel.start_stop.text() == "Stop recording"


def check_spectrum(window) -> None:
    view = window.spectrum_view
    assert view.spectrum is not None and data_size(view.curve) > 100
    labels = [item.toPlainText() for item in view.labels if item.isVisible()]
    assert "f" in labels, labels  # the drive's line, named
    # the drive's frequency as the tach measures it (whole samples between its pulses)
    assert view.drive_line.isVisible() and view.drive_line.value() == pytest.approx(10.0, abs=0.01)


def check_poincare(window) -> None:
    view = window.poincare_view
    points = view.accumulator.theta.size
    assert points >= 5 and len(view.scatter.data) == points
    assert view.count.text() == f"{points} points"
    assert view.plot.getAxis("bottom").labelText == "angle at the pulse (deg)"
    assert view.plot.getAxis("left").labelText == "angular velocity (deg/s)"


def check_phase_portrait(window) -> None:
    assert data_size(window.phase_view.curve) > 100


def check_replay(window) -> None:
    assert isinstance(window.session, ReplaySession)
    assert window.source_label.text() == "replay of live.h5"
    assert window.replay_panel.isEnabled() and " s of " in window.replay_panel.time.text()
    assert data_size(window.time_view.angle_curve) > 100
    assert window.drive_label.text().startswith("drive: 10.000 Hz")


def check_analysis(window) -> None:
    panel = window.analysis_panel
    assert panel.overlay is not None and data_size(panel.model_curve) > 100
    # the record is the screenshot plan's own simulation (the project's integrator): the
    # view is checked drawn with an explanation, not which cause it names (that is tested
    # on independent records: docs/development.md, "Which test names each cause")
    assert panel.explained is not None
    assert panel.explanation.toPlainText().startswith(f"cause: {panel.explained['cause']}")
    assert panel.report.toPlainText().startswith("experiment: free_decay")
    assert isinstance(window.session, ReplaySession)  # analysed while the replay played on


CHECKS = {
    "time_traces": check_time_traces,
    "spectrum": check_spectrum,
    "poincare": check_poincare,
    "phase_portrait": check_phase_portrait,
    "replay": check_replay,
    "analysis": check_analysis,
}


def test_every_readme_screenshot_shows_its_view_and_panels_drawn(qapp, open_window, tmp_path):
    window = open_window(1280, 800)
    views = {"time": window.time_view, "spectrum": window.spectrum_view,
             "poincare": window.poincare_view, "phase": window.phase_view,
             "analysis": window.analysis_panel}
    panels = (window.connection_panel, window.shaker_panel, window.recording_panel,
              window.replay_panel, window.status_panel)
    taken = []
    for name, path in take_screenshots(window, tmp_path, QUICK):
        image = QImage(str(path))
        assert (image.width(), image.height()) == (1280, 800), name
        assert json.loads(image.text("Provenance"))["software"]["impact-rig"], name
        view = views[SHOTS[name]]
        assert window.tabs.currentWidget() is view and view.isVisible(), name
        assert_drawn_on(image, QRect(0, 0, 1280, 800), name)
        assert_drawn_on(image, region_of(view, window), f"{name}: its view")
        for panel in panels:
            assert panel.isVisible(), (name, type(panel).__name__)
        CHECKS[name](window)
        taken.append(path.name)
    assert taken == [f"{name}.png" for name in SHOTS]


def test_screenshots_are_not_written_over_without_overwrite(tmp_path, capsys):
    kept = tmp_path / "spectrum.png"
    kept.write_bytes(b"an earlier picture")
    assert main(["gui", "--screenshots", str(tmp_path)]) == 2
    assert f"{kept}: already exists; pass --overwrite" in capsys.readouterr().err
    assert main(["gui", "--screenshot", str(kept)]) == 2
    assert f"{kept}: already exists; pass --overwrite" in capsys.readouterr().err
    assert kept.read_bytes() == b"an earlier picture"
    assert main(["gui", "--screenshots", str(tmp_path), "--view", "spectrum"]) == 2
    assert "--screenshots runs every stage itself" in capsys.readouterr().err
