"""The main window on the virtual rig (DAQ on a pty, amplifier on Modbus TCP): live data,
the drive's limits and STOP, recording, sweeps (the command line's procedure: the same
file, refusal and cancel), and faults shown in plain words."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from drivers.amplifier_registers import Fault, Holding
from gui.app import MainWindow
from gui.live_sweep import StepDwell, judge_dwell
from gui.settings import AppSettings
from gui.worker import LiveSession
from hardware_sim.daq_faults import CORRUPT_CRC
from recording.reader import open_recording
from rig.cli import main
from rig.events import COMMANDED, MEASURED, StepMark
from tests.gui.conftest import run_events, wait_until

FS_HZ = 2000.0


@pytest.fixture(scope="module")
def window(qapp, tmp_path_factory):
    settings = AppSettings(str(tmp_path_factory.mktemp("settings") / "gui.ini"))
    win = MainWindow(settings)
    win.resize(1000, 700)
    win.show()
    win.open_virtual_rig(FS_HZ)
    wait_until(qapp, lambda: isinstance(win.session, LiveSession), 30, "the virtual rig to open")
    yield win
    win.shutdown()
    win.close()


def shaker(win: MainWindow):
    return win.session.devices.shaker


def amplifier_writes(win: MainWindow, register: Holding) -> list[tuple[int, ...]]:
    """Values the emulated amplifier received for one holding register (from its wire log)."""
    return [
        r.values
        for r in win.session.devices.sim.amplifier.requests
        if r.is_write and r.address == int(register)
    ]


def shown_rate_hz(win: MainWindow) -> float:
    """The sample rate the status panel shows (0 while it shows none)."""
    text = win.status_panel.text("rate")
    return float(text.split()[0].replace(",", "")) if text.endswith(" Hz") else 0.0


def test_live_data_arrives_in_the_time_plots(qapp, window):
    window.show_view("time")
    wait_until(qapp, lambda: window.data.angle.count > FS_HZ, 20, "a second of angle samples")
    run_events(qapp, 0.3)
    x, _y = window.time_view.angle_curve.getData()
    tx, _ty = window.time_view.table_curve.getData()
    assert x is not None and x.size > 100 and tx.size > 100
    assert x[-1] - x[0] > 0.9  # a scrolling window of at least the second received
    # the drawn points are the decimated newest samples: the plot ends where the data ends
    window.time_view.refresh(window.data)
    x, _y = window.time_view.angle_curve.getData()
    newest_s = (window.data.angle.end_index - 1) / FS_HZ
    assert newest_s - 0.05 <= x[-1] <= newest_s
    assert x.size <= 2 * max(100, window.time_view.angle_plot.width()) + 2
    # the panel shows the engine's own estimate once it has one (wait on that state); how
    # near the board's rate it comes under load is a benchmark figure, not asserted here
    wait_until(qapp, lambda: shown_rate_hz(window) > 0, 20, "a sample rate in the status panel")
    assert window.status_panel.text("rate").endswith(" Hz")
    assert window.status_panel.text("lost") == "0"


def test_out_of_range_amplitude_is_refused_and_never_sent(qapp, window):
    panel = window.shaker_panel
    limit_mm = window.session.limits.max_amplitude_m * 1e3
    window.session.devices.sim.amplifier.clear_log()
    panel.frequency.setValue(10.0)
    panel.amplitude_mm.setValue(limit_mm * 1.5)
    panel.enable.setChecked(True)
    panel.apply.click()
    run_events(qapp, 0.5)
    assert "outside the configured limits" in panel.message.text()
    assert "amplitude_m" in panel.message.text()
    assert amplifier_writes(window, Holding.AMPLITUDE_UM) == []
    assert amplifier_writes(window, Holding.ENABLE) == []
    # beta is the same amplitude in other words: too large a beta is refused too
    panel.beta.setValue(1.5 * window.session.limits.max_amplitude_m / panel.L_m)
    panel.apply.click()
    run_events(qapp, 0.3)
    assert "outside the configured limits" in panel.message.text()
    assert shaker(window).amplitude_m < window.session.limits.max_amplitude_m


def test_drive_shows_harmonic_labels_and_poincare_points(qapp, window):
    panel = window.shaker_panel
    panel.frequency.setValue(10.0)
    panel.beta.setValue(0.03)
    panel.ramp.setValue(20.0)
    panel.enable.setChecked(True)
    panel.apply.click()
    wait_until(
        qapp, lambda: shaker(window).measured().amplitude_m > 1.3e-3, 15, "the drive to ramp up"
    )
    assert panel.message.text() == ""
    window.poincare_view.accumulator.clear()
    edges_before = window.data.tach_edges_seen
    window.show_view("spectrum")
    run_events(qapp, 3.0)
    new_edges = window.data.tach_edges_seen - edges_before
    # the tach ticks once per drive period: the views measure the drive frequency from it
    assert window.data.drive_frequency_hz() == pytest.approx(10.0, rel=2e-3)
    spectrum = window.spectrum_view.spectrum
    assert spectrum is not None and "f" in spectrum.labels  # the drive line, named as such
    visible = [item.toPlainText() for item in window.spectrum_view.labels if item.isVisible()]
    assert "f" in visible
    # one Poincare point per tach pulse while we watched (the newest may wait for its samples,
    # one from before the clear may just have completed)
    points = window.poincare_view.accumulator.theta.size
    assert new_edges >= 5
    assert abs(points - new_edges) <= 2
    window.show_view("poincare")
    run_events(qapp, 0.2)
    assert window.poincare_view.scatter.data.size == window.poincare_view.accumulator.theta.size


def test_stop_button_ramps_the_drive_to_zero(qapp, window):
    device = shaker(window)
    if device.measured().amplitude_m < 1e-3:
        window.session.apply_drive(10.0, 1.5e-3, True, 5e-3)
        wait_until(qapp, lambda: device.measured().amplitude_m > 1e-3, 15, "the drive to run")
    window.stop_button.click()
    # the amplifier's own measurement of its output goes to zero
    wait_until(
        qapp, lambda: device.measured().amplitude_m == 0.0, 10, "the measured amplitude to reach 0"
    )
    measured = device.measured()
    assert measured.amplitude_m == 0.0 and not measured.enabled
    assert device.amplitude_m == 0.0  # setpoint zero, not just paused
    assert not window.shaker_panel.enable.isChecked()
    wait_until(
        qapp, lambda: "0.000 mm" in window.status_panel.text("drive"), 5, "status to show 0 mm"
    )


def test_record_start_stop_and_the_file(qapp, window, tmp_path):
    path = tmp_path / "gui_run.h5"
    panel = window.recording_panel
    panel.path.setText(str(path))
    panel.notes.setPlainText("recorded by the GUI test")
    window.show_view("time")
    panel.start_stop.click()
    wait_until(qapp, lambda: panel.recording, 10, "recording to start")
    run_events(qapp, 1.5)
    assert panel.elapsed.text() != "-" and panel.size.text().endswith("B")
    panel.start_stop.click()
    wait_until(qapp, lambda: "saved" in panel.message.text(), 20, "the recording to be closed")
    assert window.analysis_panel.current_recording == str(path)
    with open_recording(path) as rec:
        assert rec.info.notes == "recorded by the GUI test"
        status = rec.status()
        assert status.closed and status.stop_reason == "stopped by the operator"
        angle = rec.channel("angle")
        table = rec.channel("table")
        assert angle.values.size >= 1.2 * FS_HZ
        assert table.values.size == pytest.approx(angle.values.size, abs=200)
        assert np.all(np.diff(angle.indices) == 1) and angle.gaps.size == 0
        # the file holds exactly what the views received for the same sample indices
        ring_index, ring_values = window.data.angle.since(int(angle.indices[0]))
        common, in_file, in_ring = np.intersect1d(angle.indices, ring_index, return_indices=True)
        assert common.size > 0.9 * angle.values.size
        assert np.allclose(angle.values[in_file], ring_values[in_ring], atol=1e-6)
        assert (
            rec.pulses("tach").edge_indices.size == 0
            or rec.pulses("tach").edge_indices[0] >= angle.indices[0]
        )


def enter_sweep(
    panel, path, parameter: str, start: float, stop: float, steps: int, fixed: float, **times
) -> None:
    """Type a sweep into the recording panel as an operator would (times: settle_s, dwell_s)."""
    panel.path.setText(str(path))
    panel.notes.setPlainText("sweep notes")
    panel.sweep_parameter.setCurrentText(parameter)
    panel.sweep_from.setValue(start)
    panel.sweep_to.setValue(stop)
    panel.sweep_steps.setValue(steps)
    panel.sweep_fixed.setValue(fixed)
    panel.sweep_settle.setValue(times.get("settle_s", 0.3))
    panel.sweep_dwell.setValue(times.get("dwell_s", 0.4))
    panel.sweep_down.setChecked(True)


def sweep_on_the_command_line(path, *plan: str) -> int:
    """``impact-rig sweep --sim`` at the GUI's sample rate, with the notes enter_sweep types."""
    rig = ["--sim", "--fs", f"{FS_HZ:g}", "--notes", "sweep notes", "--quiet"]
    return main(["sweep", *rig, *plan, "--out", str(path)])


def file_shape(path) -> dict:
    """What two recordings of one sweep plan share whatever the timing: every group and
    dataset (dtype) with its attribute names; the metadata that says what was done; the
    step marks and commanded drive; whether the drive read back was logged; how it ended."""
    shape: dict = {}
    with h5py.File(path, "r") as f:
        shape["/"] = sorted(f.attrs)

        def visit(name: str, item) -> None:
            kind = str(item.dtype) if isinstance(item, h5py.Dataset) else "group"
            shape[name] = (kind, sorted(item.attrs))

        f.visititems(visit)
    with open_recording(path) as rec:
        info, steps, drive = rec.info, rec.sweep_steps(), rec.drive_log()
        shape["metadata"] = (
            info.experiment,
            info.notes,
            info.drive,
            info.extra,
            info.roles,
            info.rig,
            info.calibrations,
            info.config_toml,
        )
        shape["steps"] = steps[
            ["step", "direction", "frequency_hz", "amplitude_m", "complete"]
        ].tolist()
        shape["step spans in order"] = bool(
            np.all(steps["settle_start_index"] <= steps["dwell_start_index"])
            and np.all(steps["dwell_start_index"] < steps["dwell_end_index"])
            and np.all(steps["settle_start_index"][1:] >= steps["dwell_end_index"][:-1])
        )
        commanded = drive[drive["source"] == COMMANDED]
        shape["commanded"] = commanded[["frequency_hz", "amplitude_m", "enabled"]].tolist()
        shape["drive read back"] = bool(np.any(drive["source"] == MEASURED))
        shape["status"] = (rec.status().closed, rec.status().stop_reason)
    return shape


def test_a_gui_sweep_writes_the_file_impact_rig_sweep_writes(qapp, window, tmp_path):
    gui_path, cli_path = tmp_path / "gui_sweep.h5", tmp_path / "cli_sweep.h5"
    panel = window.recording_panel
    enter_sweep(panel, gui_path, "frequency", 8.0, 9.0, 2, 0.5)
    panel.sweep_run.click()
    wait_until(qapp, lambda: panel.sweeping, 5, "the sweep to start")
    wait_until(qapp, lambda: not panel.sweeping, 30, "the sweep to finish")
    assert panel.sweep_text.text() == "sweep completed"
    assert panel.sweep_progress.value() == 3
    assert window.analysis_panel.current_recording == str(gui_path)
    wait_until(qapp, lambda: shaker(window).measured().at_zero, 10, "the drive to stop after it")
    assert window.shaker_panel.isEnabled()  # the drive is the operator's again
    plan = ["--sweep", "frequency", "--start", "8", "--stop", "9", "--steps", "2"]
    plan += ["--amplitude-mm", "0.5", "--settle", "0.3", "--dwell", "0.4"]
    assert sweep_on_the_command_line(cli_path, *plan) == 0
    gui, cli = file_shape(gui_path), file_shape(cli_path)
    assert gui == cli
    assert gui["steps"] == [(0, 1, 8.0, 0.5e-3, 1), (1, 1, 9.0, 0.5e-3, 1), (2, -1, 8.0, 0.5e-3, 1)]
    assert gui["step spans in order"] and gui["drive read back"]
    assert gui["status"] == (True, "completed")


def test_a_live_sweeps_steps_are_judged_off_the_gui_thread_and_drawn_as_each_ends(
    qapp, window, tmp_path, monkeypatch
):
    import threading

    import gui.app

    judged_on: list[str] = []

    def judge(dwell):  # the real judge, noting the thread it ran on
        judged_on.append(threading.current_thread().name)
        return judge_dwell(dwell)

    monkeypatch.setattr(gui.app, "judge_dwell", judge)

    def step_mark(row) -> StepMark:
        return StepMark(*(row[name].item() for name in ("step", "direction", "frequency_hz",
                        "amplitude_m", "settle_start_index", "dwell_start_index",
                        "dwell_end_index")), complete=bool(row["complete"]))
    panel, view = window.recording_panel, window.sweep_view
    enter_sweep(panel, tmp_path / "judged.h5", "frequency", 10.0, 11.0, 2, 0.5,
                settle_s=0.5, dwell_s=1.5)
    panel.sweep_run.click()
    window.show_view("sweep")
    wait_until(qapp, lambda: view.table.rowCount() >= 1, 30, "the first step on the diagram")
    assert panel.sweeping  # drawn as its step ended, while the sweep runs on
    wait_until(qapp, lambda: not panel.sweeping, 30, "the sweep to finish")
    wait_until(qapp, lambda: view.table.rowCount() == 3, 20, "every step on the diagram")
    assert judged_on and all(name.startswith("gui-step-judge") for name in judged_on)
    rows = [[view.table.item(r, c).text() for c in range(3)] for r in range(3)]
    assert rows == [["0", "up", "10 Hz"], ["1", "up", "11 Hz"], ["2", "down", "10 Hz"]]
    # each step judged on its whole dwell: as the same judge finds it on the file's dwell
    with open_recording(tmp_path / "judged.h5") as rec:
        angle, edges = rec.channel("angle"), rec.pulses("tach").edge_indices
        marks = rec.sweep_steps()
    for step, mark in zip(view.steps, marks, strict=True):
        start, end = int(mark["dwell_start_index"]), int(mark["dwell_end_index"])
        select = (angle.indices >= start) & (angle.indices < end)
        tach = edges[(edges >= start) & (edges < end)] - start
        from_file = judge_dwell(StepDwell(step_mark(mark), step.setting, angle.values[select],
                                          tach, FS_HZ, (end - start) / FS_HZ))
        assert (step.regime, step.label) == (from_file.regime, from_file.label)
        np.testing.assert_allclose(step.points_rad, from_file.points_rad, atol=1e-9)
        assert step.held_s == (end - start) / FS_HZ  # the whole dwell
    up_x, up_y = view._scatter[+1].getData()
    down_x, _ = view._scatter[-1].getData()
    assert set(np.round(up_x, 6)) == {10.0, 11.0} and np.all(np.isfinite(up_y))
    assert np.all(down_x > 10.0) and np.all(down_x < 11.0)  # the way down beside the way up


@pytest.mark.parametrize("button", ["sweep_run", "stop_button"])
def test_cancelling_a_gui_sweep_stops_the_procedure_and_keeps_what_it_recorded(
    qapp, window, tmp_path, button
):
    path = tmp_path / "cancelled.h5"
    panel = window.recording_panel
    enter_sweep(panel, path, "frequency", 8.0, 9.0, 2, 0.5, settle_s=0.2, dwell_s=60.0)
    panel.sweep_run.click()
    wait_until(qapp, lambda: "dwell" in panel.sweep_text.text(), 10, "the first step's dwell")
    run_events(qapp, 0.3)
    # the toolbar shows the step under way, not the last one ended (there is none yet)
    assert window.drive_label.text().endswith("in sweep step 1 of 3")
    # the sweep button reads "Cancel sweep" while a sweep runs; STOP cancels it as well
    (panel.sweep_run if button == "sweep_run" else window.stop_button).click()
    # a bound on a hang, far below the 60 s dwell; that it stopped on request, not after
    # its dwell, is asserted below on the file: the recorded part of the dwell is short
    wait_until(qapp, lambda: not panel.sweeping, 30, "the sweep to end")
    assert panel.sweep_text.text() == "sweep stopped by the operator"
    assert panel.sweep_progress.value() == 0
    wait_until(qapp, lambda: shaker(window).measured().at_zero, 10, "the drive to reach zero")
    with open_recording(path) as rec:
        status, steps, drive = rec.status(), rec.sweep_steps(), rec.drive_log()
        angle = rec.channel("angle")
    assert status.closed and status.stop_reason == "stopped by the operator"
    # the step under way is kept, marked incomplete, with the part of its dwell recorded
    assert steps[["step", "frequency_hz", "complete"]].tolist() == [(0, 8.0, 0)]
    dwell_recorded = steps["dwell_end_index"][0] - steps["dwell_start_index"][0]
    assert 0.2 * FS_HZ <= dwell_recorded < 30 * FS_HZ  # cut short: half the 60 s dwell at most
    assert angle.indices[-1] + 1 >= steps["dwell_end_index"][0]
    assert np.all(np.diff(angle.indices) == 1)
    commanded = drive[drive["source"] == COMMANDED][["frequency_hz", "amplitude_m", "enabled"]]
    assert commanded[0].tolist() == (8.0, 0.5e-3, 1)
    assert set(commanded[1:].tolist()) == {(0.0, 0.0, 0)}  # the procedure's zero (and STOP's)
    assert np.any(drive["source"] == MEASURED)  # the procedure's drive monitor ran, and ended


def test_a_gui_sweep_beyond_the_limits_is_refused_before_anything_moves_as_on_the_command_line(
    qapp, window, tmp_path, capsys
):
    path = tmp_path / "too_fast.h5"
    panel = window.recording_panel
    window.session.devices.sim.amplifier.clear_log()
    enter_sweep(panel, path, "frequency", 30.0, 60.0, 4, 1.0)
    panel.sweep_run.click()
    wait_until(qapp, lambda: panel.sweep_text.text().startswith("Refused"), 10, "the refusal")
    assert not panel.sweeping
    for register in (Holding.FREQUENCY_MHZ_HI, Holding.AMPLITUDE_UM, Holding.ENABLE):
        assert amplifier_writes(window, register) == []
    assert not path.exists()
    plan = ["--sweep", "frequency", "--start", "30", "--stop", "60", "--steps", "4"]
    assert sweep_on_the_command_line(tmp_path / "cli.h5", *plan, "--amplitude-mm", "1") == 2
    cli_message = capsys.readouterr().err.strip().removeprefix("impact-rig sweep: error: ")
    assert panel.sweep_text.text() == f"Refused: {cli_message}"
    assert "frequency_hz = 50.0" in cli_message and "default_rig.toml" in cli_message


def test_amplifier_fault_appears_in_plain_words(qapp, window):
    window.session.devices.sim.trip(Fault.OVER_TEMPERATURE)
    wait_until(
        qapp,
        lambda: "over-temperature" in window.status_panel.text("faults"),
        10,
        "the fault in the status panel",
    )
    assert window.status_panel.fields["faults"].styleSheet().startswith("color: #b00000")
    window.shaker_panel.clear_faults.click()
    wait_until(qapp, lambda: window.status_panel.text("faults") == "none", 10, "the fault to clear")


def test_lost_daq_frames_appear_as_lost_samples(qapp, window):
    faults = window.session.devices.sim.daq.faults
    faults.corrupt_crc(frames=2)
    wait_until(
        qapp,
        lambda: sum(record.kind == CORRUPT_CRC for record in faults.log) == 2,
        10,
        "two frames damaged on the wire",
    )
    # every sample the board's own log says the faults cost, counted once per sampled
    # channel (the angle and the table lose the same board samples)
    wait_until(
        qapp,
        lambda: window.session.stats().lost_per_stream["angle"] >= faults.samples_lost(),
        10,
        "the engine to count the lost samples",
    )
    stats = window.session.stats()
    board_lost = faults.samples_lost()
    assert board_lost > 0
    assert stats.lost_per_stream["angle"] == stats.lost_per_stream["table"] == board_lost
    assert stats.samples_lost == 2 * board_lost
    shown = f"{stats.samples_lost:,} (gaps in the data)"
    wait_until(qapp, lambda: window.status_panel.text("lost") == shown, 5, f"the panel: {shown}")
    assert window.status_panel.fields["lost"].styleSheet() == "color: #b00000"
