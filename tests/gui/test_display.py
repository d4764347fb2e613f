"""What the window shows a person: every panel at 1280x800, the drive and sweep step, axes in
seconds from the start, degrees and mm scaled to the data, and the Analysis tab's explanation
of a record (the cause, the residual before and after)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, QRect, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication, QScrollArea

from analysis.estimate_text import NOT_DETERMINED
from analysis.model import RigParameters
from gui.model_overlay import explanation_lines
from gui.units import DISPLAY, axis_range, parameter_unit
from reference.simulator import Pendulum, TableMotion, simulate_reference
from rig.events import DriveSetting, StepMark
from tests.gui.conftest import run_events, wait_until
from tests.gui.recordings import RIG, write_recording
from tests.tolerance import Z_95, Z_999

FS = 1000.0
DRIVE_HZ = 2.0
L_M = 0.046
FIRST_INDEX = 1_234_567  # device time is far from the start of the record
DEG = 180.0 / math.pi


@pytest.fixture
def window(open_window):
    return open_window(1280, 800)


def test_every_panel_shows_at_1280_by_800_without_scrolling(qapp, window):
    run_events(qapp, 0.2)
    assert (window.width(), window.height()) == (1280, 800)
    inside = QRect(0, 0, 1280, 800)
    panels = (
        window.connection_panel,
        window.shaker_panel,
        window.status_panel,
        window.recording_panel,
        window.replay_panel,
        window.tabs,
    )
    for panel in panels:
        box = QRect(panel.mapTo(window, panel.rect().topLeft()), panel.geometry().size())
        assert panel.isVisible() and box.width() > 0 and box.height() > 0, panel
        assert inside.contains(box), (type(panel).__name__, box)
    scroll = window.findChild(QScrollArea)
    assert scroll.verticalScrollBar().maximum() == 0
    assert scroll.horizontalScrollBar().maximum() == 0


@pytest.fixture(scope="module")
def sweep_recording(tmp_path_factory):
    """Six seconds of a 2 Hz swing (0.1 rad) on a table moving 1 mm, a two-step sweep (1 mm,
    then 1.5 mm from 3 s), recorded by a board whose sample count began long before."""
    n = int(6 * FS)
    t = np.arange(n) / FS
    angle = 0.1 * np.sin(2 * np.pi * DRIVE_HZ * t)
    table = 1e-3 * np.sin(2 * np.pi * DRIVE_HZ * t)
    half = n // 2
    steps = [
        StepMark(0, 1, DRIVE_HZ, 1e-3, FIRST_INDEX, FIRST_INDEX + 1000, FIRST_INDEX + half),
        StepMark(1, 1, DRIVE_HZ, 1.5e-3, FIRST_INDEX + half, FIRST_INDEX + half + 1000,
                 FIRST_INDEX + n),
    ]
    path = tmp_path_factory.mktemp("rec") / "sweep.h5"
    return write_recording(
        path, angle, FS, table=table, tach_period=int(FS / DRIVE_HZ),
        drive=DriveSetting(0.0, FIRST_INDEX, DRIVE_HZ, 1e-3, True),
        annotations=[DriveSetting(3.0, FIRST_INDEX + half, DRIVE_HZ, 1.5e-3, True), *steps],
        first_index=FIRST_INDEX, rig={**RIG, "L_m": L_M},
    )


def test_replay_shows_the_drive_the_step_and_axes_scaled_in_seconds_degrees_and_mm(
    qapp, window, sweep_recording
):
    window.replay_panel.speed.setCurrentText("max")
    window.open_replay(str(sweep_recording))
    wait_until(qapp, lambda: window.session.finished, 20, "the replay to finish")
    run_events(qapp, 0.3)
    view = window.time_view
    # time from the start of the record, the last window_s seconds of it
    x, _ = view.angle_curve.getData()
    assert x[-1] == pytest.approx(5.999)
    (x_low, x_high), (a_low, a_high) = view.angle_plot.viewRange()
    assert (x_low, x_high) == pytest.approx((0.999, 5.999))
    # the angle in degrees: +-5.73 deg with a margin, and room above for the tach marks
    assert -6.5 < a_low < -0.1 * DEG < 0.1 * DEG < a_high < 9.0
    # the table at its 1 mm, not hundreds of mm
    t_low, t_high = view.table_plot.viewRange()[1]
    assert -1.2 < t_low < -1.0 and 1.0 < t_high < 1.2
    assert view.angle_plot.getAxis("left").labelText == "angle (deg)"
    assert view.table_plot.getAxis("left").labelText == "table (mm)"
    assert view.table_plot.getAxis("bottom").labelText == "time from the start (s)"
    # the drive of the second step, its beta from the recording's L, and the step
    assert window.drive_label.text() == (
        f"drive: 2.000 Hz, 1.500 mm, β = A/L = {1.5e-3 / L_M:.4f}   |   in sweep step 2 of 2"
    )
    markers = [m for m in view.step_markers if m.isVisible()]
    assert [(m.value(), m.label.format) for m in markers] == [(pytest.approx(3.0), "step 2")]


def wheel(plot, notches: int) -> None:
    """Turn the mouse wheel over the middle of ``plot``, as a hand does (Qt's own event)."""
    viewport = plot.viewport()
    centre = QPointF(viewport.width() / 2, viewport.height() / 2)
    event = QWheelEvent(centre, QPointF(viewport.mapToGlobal(centre.toPoint())), QPoint(),
                        QPoint(0, 120 * notches), Qt.MouseButton.NoButton,
                        Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(viewport, event)


def test_a_view_zoomed_by_hand_stays_until_its_auto_range_button(qapp, window, sweep_recording):
    window.replay_panel.speed.setCurrentText("1x")
    window.open_replay(str(sweep_recording))
    view = window.time_view
    wait_until(qapp, lambda: view.angle_curve.getData()[0] is not None
               and view.angle_curve.getData()[0].size > 0, 10, "the first frames")
    run_events(qapp, 0.5)
    following = view.angle_plot.viewRange()
    wheel(view.angle_plot, 3)  # zoom in
    run_events(qapp, 0.6)  # frames go on drawing the replay
    zoomed = view.angle_plot.viewRange()
    assert zoomed[0][1] - zoomed[0][0] < 0.8 * (following[0][1] - following[0][0])
    assert zoomed[1][1] - zoomed[1][0] < 0.8 * (following[1][1] - following[1][0])
    run_events(qapp, 0.6)
    held = np.ravel(view.angle_plot.viewRange())
    assert held == pytest.approx(np.ravel(zoomed))  # where the hand put it
    auto = view.angle_plot.getPlotItem().autoBtn
    auto.clicked.emit(auto)  # the "A" button pyqtgraph shows on a plot zoomed by hand
    run_events(qapp, 0.5)
    x_low, x_high = view.angle_plot.viewRange()[0]
    assert x_high - x_low == pytest.approx(view.window_s.value())  # following the data again
    window.replay_panel.speed.setCurrentText("max")


def test_a_still_trace_is_drawn_on_its_minimum_span_not_blown_up(qapp, window, tmp_path):
    angle = 0.02 + 1e-6 * np.sin(np.arange(3000) / 7.0)
    path = write_recording(tmp_path / "still.h5", angle, FS, table=np.full(3000, 2e-3))
    window.replay_panel.speed.setCurrentText("max")
    window.open_replay(str(path))
    wait_until(qapp, lambda: window.session.finished, 20, "the replay to finish")
    run_events(qapp, 0.3)
    a_low, a_high = window.time_view.angle_plot.viewRange()[1]
    assert a_low < 0.02 * DEG < a_high
    assert a_high - a_low >= DISPLAY["angle"].minimum_span
    t_low, t_high = window.time_view.table_plot.viewRange()[1]
    assert t_low < 2.0 < t_high
    assert t_high - t_low == pytest.approx(DISPLAY["displacement"].minimum_span)
    assert window.drive_label.text() == "drive: none recorded"


def test_axis_range_spans_the_data_or_its_minimum():
    assert axis_range(np.array([-2.0, 3.0]), 1.0) == pytest.approx((-2.25, 3.25))
    assert axis_range(np.array([5.0, 5.0, np.nan]), 2.0) == pytest.approx((4.0, 6.0))
    assert axis_range(np.array([np.nan]), 1.0) is None


def test_parameters_show_in_display_units_by_their_si_names():
    symbol, unit = parameter_unit("theta_b_rad")
    assert (symbol, unit.unit, unit.show(math.pi)) == ("theta_b", "deg", pytest.approx(180.0))
    assert parameter_unit("L_m")[1].unit == "mm"
    assert parameter_unit("theta_dot0_rad_s")[1].unit == "deg/s"
    for compound in ("Tc_N_m", "mu0_s_per_m", "c2_per_rad", "K_N_per_m1.5", "k3"):
        assert parameter_unit(compound) is None, compound


def test_explanation_reads_intervals_and_units_for_people():
    report = {
        "cause": "barrier_offset",
        "causes": [{
            "cause": "barrier_offset",
            "parameters": {"theta_b_rad": {"value": 0.01, "ci95": [0.009, 0.011]},
                           "c": {"value": 2.856e-33, "ci95": [2.856e-33, 2.856e-33]}},
            "gain": {"information_criterion_delta": 250.0, "heldout_ratio": 0.4,
                     "invariant_ratio": None},
        }],
        "baseline": {"rms_residual": 0.01},
        "extended": {"rms_residual": 0.001},
        "noise_rad": 0.001,
        "regime": {"label": "period 2"},
        "unexplained": False,
        "residual_findings": [{"kind": "line", "text": "a line at 50 Hz"}],
        "warnings": [],
    }
    lines = explanation_lines(report)
    assert lines[0] == "cause: barrier_offset"
    assert f"    theta_b = {0.01 * DEG:.4g}   95% CI [{0.009 * DEG:.4g}, {0.011 * DEG:.4g}] deg" \
        in lines
    assert f"    c = 2.856e-33 ({NOT_DETERMINED})" in lines
    assert "    gain: information criterion gain 250; held-out error ratio 0.4" in lines
    assert f"residual before (baseline): {0.01 * DEG:.3g} deg rms = 10 x the noise" in lines
    assert f"residual after (with barrier_offset): {0.001 * DEG:.3g} deg rms = 1 x the noise" \
        in lines
    assert "regime: period 2" in lines
    assert "residual finding (line): a line at 50 Hz" in lines


def test_analysis_tab_explains_a_decay_with_dry_friction(qapp, window, tmp_path):
    # the record comes from the independent reference simulator (scipy DOP853 with stiction
    # events), never the project's integrator and friction code, which the analysis shares
    rig = RigParameters(g_m_s2=RIG["g"])
    swing = 0.15
    # dry friction losing as much per cycle at the start as the viscous damping does
    torque = 2 * math.pi * rig.zeta * swing * rig.m_kg * rig.L_m**2 * rig.omega_rad_s**2 / 4
    pendulum = Pendulum(m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta,
                        K_n=rig.K_N_per_m1_5, mu0_s_per_m=rig.mu0_s_per_m, g_m_s2=rig.g_m_s2,
                        barrier=False, Tc_N_m=torque)
    fs = 500.0
    t = np.arange(round(10.0 * fs)) / fs
    theta = simulate_reference(pendulum, TableMotion(), swing, 0.0, t).theta_rad
    measured = theta + np.random.default_rng(5).normal(0, 2e-4, theta.size)
    path = write_recording(tmp_path / "friction.h5", measured, fs, experiment="free_decay")
    window.show_view("analysis")
    panel = window.analysis_panel
    panel.path.setText(str(path))
    panel.explain.click()
    assert not panel.explain.isEnabled() and not panel.run.isEnabled()  # on the worker thread
    assert not panel.busy.isHidden()
    wait_until(qapp, lambda: panel.explained is not None, 120, "the analysis")
    assert panel.explain.isEnabled() and panel.busy.isHidden()
    report = panel.explained
    text = panel.explanation.toPlainText().splitlines()
    assert report["cause"] == "coulomb_friction"
    assert text[0] == "cause: coulomb_friction" == panel.state.text()
    fitted = report["causes"][0]["parameters"]["Tc_N_m"]
    low, high = fitted["ci95"]  # the truth inside the 99.9 % interval
    assert abs(fitted["value"] - torque) <= (high - low) / 2 * Z_999 / Z_95, fitted
    assert any(line.startswith("    Tc_N_m = ") and "95% CI" in line for line in text)
    before, after = report["baseline"]["rms_residual"], report["extended"]["rms_residual"]
    noise = report["noise_rad"]
    assert before > 10 * noise and after < 1.5 * noise  # the cause explains the record
    assert f"residual before (baseline): {before * DEG:.3g} deg rms = " \
        f"{before / noise:.3g} x the noise" in text
    assert f"residual after (with coulomb_friction): {after * DEG:.3g} deg rms = " \
        f"{after / noise:.3g} x the noise" in text
    # the plot draws the angle fitted with the baseline's and the extended model's responses
    assert panel.key == ["measured", "baseline model", "baseline + coulomb_friction"]
    title = panel.plot.getPlotItem().titleLabel.text  # the key, above the data
    assert all(name in title for name in panel.key)
    curves = {name: getattr(panel, f"{name}_curve").getData()
              for name in ("measured", "model", "extended")}
    assert all(curve[0].size > 100 for curve in curves.values())
    assert panel.plot.getAxis("left").labelText == "angle (deg)"

    def rms_from_measured(name):
        on_data = np.interp(curves["measured"][0], *curves[name])
        return np.sqrt(np.mean((on_data - curves["measured"][1]) ** 2))

    assert rms_from_measured("extended") < 0.5 * rms_from_measured("model")  # as shown, in deg
    # the stages it went through were shown as it ran, and stay below the explanation
    assert "fitting the baseline model" in text[text.index("how the analysis went:"):]
