"""The main window on the virtual rig (DAQ on a pty, amplifier on Modbus TCP): live data,
the drive's limits and STOP, recording, sweeps, and faults shown in plain words."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.recording_file import open_recording
from drivers.amplifier_registers import Fault, Holding
from gui.app import MainWindow
from gui.settings import AppSettings
from gui.worker import LiveSession
from hardware_sim.daq_faults import CORRUPT_CRC
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
    assert window.status_panel.text("rate").endswith("Hz")
    rate = float(window.status_panel.text("rate").split()[0].replace(",", ""))
    assert rate == pytest.approx(FS_HZ, rel=0.1)
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


def test_sweep_runner_records_every_step(qapp, window, tmp_path):
    path = tmp_path / "sweep.h5"
    panel = window.recording_panel
    panel.path.setText(str(path))
    panel.sweep_parameter.setCurrentText("frequency")
    panel.sweep_from.setValue(8.0)
    panel.sweep_to.setValue(9.0)
    panel.sweep_steps.setValue(2)
    panel.sweep_fixed.setValue(0.5)
    panel.sweep_settle.setValue(0.3)
    panel.sweep_dwell.setValue(0.4)
    panel.sweep_down.setChecked(True)
    panel.sweep_run.click()
    wait_until(qapp, lambda: panel.sweeping, 5, "the sweep to start")
    wait_until(qapp, lambda: not panel.sweeping, 30, "the sweep to finish")
    assert "completed" in panel.sweep_text.text()
    assert panel.sweep_progress.value() == 3
    wait_until(qapp, lambda: shaker(window).measured().at_zero, 10, "the drive to stop after it")
    with open_recording(path) as rec:
        steps = rec.sweep_steps()
        assert list(steps["frequency_hz"]) == [8.0, 9.0, 8.0]
        assert list(steps["direction"]) == [1, 1, -1]
        assert all(steps["complete"])
        assert np.all(np.isclose(steps["amplitude_m"], 0.5e-3))
        assert rec.status().stop_reason == "completed"


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
