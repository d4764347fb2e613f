"""The README's screenshots, taken by the application itself (``impact-rig gui --screenshots
DIR``): the virtual rig live in every view while it records, that recording replayed, and a
free decay with dry friction identified and explained in the Analysis tab while the replay
plays on.

:func:`take_screenshots` drives a main window through these stages and yields after each
picture, the window still showing it, so that a test can check what the picture shows.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtWidgets import QApplication, QWidget

from analysis import quantities as q
from analysis.provenance import png_metadata
from gui.worker import LiveSession, ReplaySession

if TYPE_CHECKING:  # the window's type, for the hints (gui.app imports the whole application)
    from gui.app import MainWindow

POLL_S = 0.01
WAIT_FOR_VIEW_S = 30.0


class ScreenshotError(RuntimeError):
    """A stage did not come about (the rig did not open, an analysis failed); says which."""


@dataclass(frozen=True)
class ScreenshotPlan:
    """How long each stage runs: the README's pictures, or a test's quicker ones."""

    live_s: float = 14.0  # the drive runs this long before the live views: period 2 settled
    view_s: float = 1.5  # each view draws this long before it is saved
    replay_s: float = 6.0  # the recording plays (at 1x) this long before it is saved
    drive_hz: float = 10.0
    beta: float = 0.06  # a period-2 response at 10 Hz
    decay_s: float = 8.0  # the free decay the Analysis tab explains (still after about 7 s)
    timeout_s: float = 300.0  # the longest any stage may take (the analysis takes longest)


README_PLAN = ScreenshotPlan()

# picture name -> the view it shows; in the order they are taken
SHOTS = {
    "time_traces": "time",
    "spectrum": "spectrum",
    "poincare": "poincare",
    "phase_portrait": "phase",
    "replay": "time",
    "analysis": "analysis",
}


def screenshot_files(folder: str | Path) -> list[Path]:
    """The PNG files :func:`take_screenshots` writes into ``folder``."""
    return [Path(folder) / f"{name}.png" for name in SHOTS]


def save_window(window: QWidget, path: str | Path) -> Path:
    """Save what ``window`` shows as a PNG carrying the software that made it (the same text
    chunks as the reports' figures)."""
    image = window.grab().toImage()
    for key, value in png_metadata().items():
        image.setText(key, value)
    if not image.save(str(path)):
        raise ScreenshotError(f"{path}: cannot write the screenshot")
    return Path(path)


def take_screenshots(
    window: MainWindow, folder: str | Path, plan: ScreenshotPlan = README_PLAN
) -> Iterator[tuple[str, Path]]:
    """Run ``window`` through the stages, saving each of SHOTS into
    ``folder``; yields (name, path) after each, with the window still showing it."""
    with TemporaryDirectory(prefix="impact-rig-screenshots-") as scratch:
        recording = Path(scratch) / "live.h5"
        _go_live(window, plan, recording)
        for name in ("time_traces", "spectrum", "poincare", "phase_portrait"):
            yield name, _shoot(window, folder, name, plan.view_s)
        _stop_recording(window, plan, recording)
        window.replay_panel.speed.setCurrentText("1x")
        window.open_replay(str(recording))
        if not isinstance(window.session, ReplaySession):
            raise ScreenshotError(f"cannot replay {recording}: {window.last_error}")
        yield "replay", _shoot(window, folder, "replay", plan.replay_s)
        _explain(window, plan, friction_decay(Path(scratch) / "friction_decay.csv", plan.decay_s))
        yield "analysis", _shoot(window, folder, "analysis", plan.view_s)


def _go_live(window: MainWindow, plan: ScreenshotPlan, recording: Path) -> None:
    """Open the virtual rig, drive it and record from the start; run ``plan.live_s`` (the
    Poincare section cleared half way: it shows the settled response, not the ramp)."""
    window.open_virtual_rig()
    _wait_until(lambda: isinstance(window.session, LiveSession) or window.last_error,
                plan.timeout_s, "the virtual rig to open")
    if not isinstance(window.session, LiveSession):
        raise ScreenshotError(f"cannot open the virtual rig: {window.last_error}")
    shaker = window.shaker_panel
    shaker.frequency.setValue(plan.drive_hz)
    shaker.beta.setValue(plan.beta)
    shaker.enable.setChecked(True)
    shaker.apply.click()
    recorder = window.recording_panel
    recorder.path.setText(str(recording))
    recorder.notes.setPlainText(f"{plan.drive_hz:g} Hz, beta = {plan.beta:g}: period 2")
    recorder.start_stop.click()
    _wait_until(lambda: window.session.recording is not None, plan.timeout_s,
                "the recording to start")
    _run_events(plan.live_s / 2)
    window.poincare_view.clear_button.click()
    _run_events(plan.live_s / 2)


def _stop_recording(window: MainWindow, plan: ScreenshotPlan, recording: Path) -> None:
    window.recording_panel.start_stop.click()
    _wait_until(lambda: window.analysis_panel.current_recording == str(recording),
                plan.timeout_s, "the recording to close")


def _explain(window: MainWindow, plan: ScreenshotPlan, decay: Path) -> None:
    """Identify the decay (the model drawn over it), then explain it (analyze)."""
    window.show_view("analysis")
    panel = window.analysis_panel
    panel.path.setText(str(decay))
    for button, what in ((panel.run, "identification"), (panel.explain, "explanation")):
        button.click()
        _wait_until(button.isEnabled, plan.timeout_s, f"the {what}")
        if panel.state.text().startswith("cannot "):
            raise ScreenshotError(f"{decay}: {panel.state.text()}")


def _shoot(window: MainWindow, folder: str | Path, name: str, settle_s: float) -> Path:
    """Bring the picture's view to the front, let it draw ``settle_s``, save the window."""
    window.show_view(SHOTS[name])
    _run_events(settle_s)
    if name == "spectrum":  # computed on its own thread, which a busy machine delays
        _wait_until(lambda: window.spectrum_view.spectrum is not None, WAIT_FOR_VIEW_S,
                    "the first spectrum")
    return save_window(window, Path(folder) / f"{name}.png")


def friction_decay(path: Path, duration_s: float) -> Path:
    """A simulated free decay of the default rig with dry friction (losing as much per cycle
    as the viscous damping at the start) and 0.2 mrad of noise, as an exchange CSV."""
    from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
    from analysis.model import Drive, Model, RigParameters
    from analysis.provenance import provenance
    from analysis.simulate import SimulationSettings, simulate

    rig = RigParameters()
    swing_rad, fs_hz = 0.15, 500.0
    torque = 2 * math.pi * rig.zeta * swing_rad * rig.m_kg * rig.L_m**2 * rig.omega_rad_s**2 / 4
    model = Model(rig=rig, drive=Drive(), barrier=False).with_extension(
        "coulomb_friction", Tc_N_m=torque
    )
    run = simulate(model, swing_rad,
                   settings=SimulationSettings(duration_s, fs_hz, poincare_phase=None))
    angle = np.asarray(run.theta, dtype=float) + np.random.default_rng(5).normal(
        0.0, 2e-4, run.theta.size)
    meta = ExchangeMeta(
        experiment="free_decay",
        rig={q.m_kg: rig.m_kg, q.l_m: rig.l_m, q.R_m: rig.R_m, "g": rig.g_m_s2},
        notes=f"simulated free decay with dry friction, Tc_N_m = {torque:.4g}",
        extra={"provenance": provenance()},
    )
    write_exchange(path, ExchangeRecord(np.arange(angle.size) / fs_hz, angle, meta))
    return path


def _run_events(seconds: float) -> None:
    """Let the Qt event loop run for ``seconds``."""
    app = QApplication.instance()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        app.processEvents()
        time.sleep(POLL_S)


def _wait_until(condition: Callable[[], object], timeout_s: float, what: str) -> None:
    """Run the event loop until ``condition()`` is true; ScreenshotError naming ``what``
    after ``timeout_s``."""
    app = QApplication.instance()
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise ScreenshotError(f"timed out after {timeout_s:g} s waiting for {what}")
        app.processEvents()
        time.sleep(POLL_S)
