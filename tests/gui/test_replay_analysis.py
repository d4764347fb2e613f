"""Replay shows the recorded data in the live views (play, pause, seek, speed); the analysis
panel identifies a recording on its worker thread and overlays the model's response."""

from __future__ import annotations

import numpy as np
import pytest

from gui.worker import ReplaySession
from reference.oracle import free_decay
from rig.events import DriveSetting
from tests.gui.conftest import run_events, wait_until
from tests.gui.recordings import write_recording
from tests.tolerance import Z_95, Z_999

FS = 1000.0
DRIVE_HZ = 2.0
AMPLITUDE = 0.1


@pytest.fixture
def window(open_window):
    return open_window(900, 600)


@pytest.fixture(scope="module")
def sine_recording(tmp_path_factory):
    """Six seconds of a 2 Hz sine with a tach pulse at phase 0 of every period."""
    t = np.arange(int(6 * FS)) / FS
    angle = AMPLITUDE * np.sin(2 * np.pi * DRIVE_HZ * t)
    table = 1e-3 * np.sin(2 * np.pi * DRIVE_HZ * t)
    path = tmp_path_factory.mktemp("rec") / "sine.h5"
    drive = DriveSetting(0.0, 0, DRIVE_HZ, 1e-3, True)
    return write_recording(
        path, angle, FS, table=table, tach_period=int(FS / DRIVE_HZ), drive=drive
    ), angle


def test_replay_shows_every_recorded_sample_in_the_views(qapp, window, sine_recording):
    path, angle = sine_recording
    window.replay_panel.speed.setCurrentText("max")
    window.open_replay(str(path))
    assert isinstance(window.session, ReplaySession)
    wait_until(qapp, lambda: window.session.finished, 20, "the replay to finish")
    run_events(qapp, 0.3)
    indices, values = window.data.angle.latest()
    assert np.array_equal(indices, np.arange(angle.size))
    assert np.allclose(values, angle, atol=1e-6)  # stored as float32
    x, _ = window.time_view.angle_curve.getData()
    assert x is not None and x[-1] == pytest.approx((angle.size - 1) / FS, abs=0.01)
    # the same views as live: drive from the tach, Poincare points at phase 0 of the sine
    assert window.data.drive_frequency_hz() == pytest.approx(DRIVE_HZ)
    acc = window.poincare_view.accumulator
    assert acc.theta.size >= 10
    assert np.allclose(acc.theta, 0.0, atol=1e-4)
    assert np.allclose(acc.theta_dot, 2 * np.pi * DRIVE_HZ * AMPLITUDE, rtol=1e-2)
    assert window.data.drive is not None and window.data.drive.frequency_hz == DRIVE_HZ
    assert not window.replay_panel.playing and "(end)" in window.replay_panel.time.text()


def test_replay_seek_pause_and_speed(qapp, window, sine_recording):
    path, angle = sine_recording
    window.replay_panel.speed.setCurrentText("max")
    window.open_replay(str(path))
    wait_until(qapp, lambda: window.session.finished, 20, "the first pass")
    window.replay_seek(0.5)
    wait_until(qapp, lambda: window.session.finished, 20, "the replay after the seek")
    run_events(qapp, 0.2)
    indices, values = window.data.angle.latest()
    assert 2900 <= indices[0] <= 3000  # from the block holding the seek point, no earlier
    assert np.allclose(values, angle[indices], atol=1e-6)
    # real-time play can be paused: nothing arrives while paused, play continues where it was
    window.replay_panel.speed.setCurrentText("1x")
    window.replay_seek(0.0)
    run_events(qapp, 0.6)
    window.replay_pause()
    run_events(qapp, 0.1)
    held = window.data.angle.end_index
    assert held is not None and 0 < held < angle.size
    run_events(qapp, 0.5)
    assert window.data.angle.end_index == held
    window.replay_speed("max")
    window.replay_play()
    wait_until(qapp, lambda: window.session.finished, 20, "the replay to run to the end")
    run_events(qapp, 0.2)
    indices, _ = window.data.angle.latest()
    assert indices[-1] == angle.size - 1
    assert np.all(np.diff(indices) == 1)  # resumed without a hole or a repeat


def test_analysis_identifies_a_free_decay_and_overlays_the_model(qapp, window, tmp_path):
    L_m, zeta, g = 0.046, 0.007, 9.81
    fs = 500.0
    # scipy's DOP853 on the pendulum equation, never the fit's own simulation of it
    t, theta = free_decay(0.12, zeta, L_m, duration_s=8.0, fs_hz=fs, g=g)
    noise = 2e-4
    measured = theta + np.random.default_rng(11).normal(0, noise, t.size)
    path = write_recording(tmp_path / "decay.h5", measured, fs, experiment="free_decay")
    window.show_view("analysis")
    panel = window.analysis_panel
    panel.path.setText(str(path))
    panel.run.click()
    assert not panel.run.isEnabled()  # busy: the fit runs on the analysis thread
    wait_until(qapp, lambda: panel.overlay is not None, 120, "the identification")
    result = panel.overlay.result
    for key, truth in (("L_m", L_m), ("zeta", zeta)):  # inside the 99.9 % interval
        low, high = result[key].ci95
        assert abs(result[key].value - truth) <= (high - low) / 2 * Z_999 / Z_95, result[key]
    # the model's response lies on the data within the noise
    assert panel.overlay.rms_difference < 1.5 * noise
    x, _ = panel.model_curve.getData()
    assert x is not None and x.size > 100
    assert "L_m" in panel.report.toPlainText()


def test_analysis_reports_a_record_it_cannot_identify(qapp, window, tmp_path):
    t = np.arange(2000) / 500.0
    path = write_recording(tmp_path / "flat.h5", np.zeros(t.size), 500.0, experiment="free_decay")
    window.analysis_panel.path.setText(str(path))
    window.analysis_panel.run.click()
    wait_until(
        qapp, lambda: window.analysis_panel.run.isEnabled(), 60, "the identification to give up"
    )
    assert window.analysis_panel.state.text().startswith("cannot identify:")
