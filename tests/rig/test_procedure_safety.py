"""Whatever stops a procedure (Ctrl-C, a device failure, a bad path), the shaker ends at zero
and the recording is a valid file saying why it stopped."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from recording.reader import open_recording
from rig.cli import main
from rig.config import load_config
from rig.devices import open_rig
from rig.engine import AcquisitionError
from rig.procedures import SweepPlan, TimedPlan, record_timed, run_sweep
from tests.rig.streams import TachStream


@pytest.fixture(scope="module")
def devices():
    """The virtual rig, reached by the real drivers over pty + Modbus TCP."""
    rig = open_rig(load_config(), sample_rate_hz=2000.0)
    yield rig
    rig.close()


def _wait_at_zero(shaker):
    return shaker.wait_until(lambda m: m.at_zero and not m.enabled, 5.0, "at zero")


def test_ctrl_c_during_a_sweep_ramps_the_shaker_to_zero_and_marks_the_step_incomplete(
    devices, tmp_path
):
    path = tmp_path / "sweep.h5"

    def operator_presses_ctrl_c(text):
        if text.startswith("step 2/3") and "dwell" in text:
            raise KeyboardInterrupt

    plan = SweepPlan("amplitude", (0.5e-3, 1.0e-3), 5.0, settle_s=0.6, dwell_s=0.6)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(devices, path, plan, progress=operator_presses_ctrl_c)
    measured = _wait_at_zero(devices.shaker)
    assert measured.amplitude_m <= 1e-6  # one register count
    with open_recording(path) as rec:
        status = rec.status()
        steps = rec.sweep_steps()
        drive = rec.drive_log()
        drive = drive[drive["source"] == 0]  # commanded, not read back
        samples = len(rec.channel("angle"))
    assert status.closed and status.stop_reason == "interrupted (Ctrl-C)"
    assert steps["complete"].tolist() == [1, 0]
    assert steps["amplitude_m"].tolist() == [0.5e-3, 1.0e-3]
    assert drive["enabled"][-1] == 0 and drive["amplitude_m"][-1] == 0.0
    assert samples > 2000


class _TachThatCannotStart(TachStream):
    """A tach input whose start fails, as a board refusing to stream would."""

    def start(self) -> None:
        raise OSError("board refused to stream")


def test_a_stream_that_cannot_start_leaves_a_closed_file_saying_why(devices, tmp_path):
    path = tmp_path / "never_started.h5"
    broken = dataclasses.replace(devices, tach=_TachThatCannotStart())
    plan = TimedPlan("free_decay", duration_s=1.0)
    with pytest.raises(AcquisitionError, match="tach: cannot start"):
        record_timed(broken, path, plan)
    with open_recording(path) as rec:
        status = rec.status()
    assert status.closed and "board refused to stream" in status.stop_reason


def test_a_daq_that_goes_away_stops_the_drive_and_keeps_the_data(tmp_path):
    # it does not come back within the rig file's reconnect_for_s: the run ends
    config = load_config()
    config = dataclasses.replace(config, daq=dataclasses.replace(config.daq, reconnect_for_s=0.5))
    rig = open_rig(config, sample_rate_hz=2000.0)
    path = tmp_path / "unplugged.h5"
    seen = []

    def unplug_after_a_second(text):
        seen.append(text)
        if text.startswith("recording") and len(seen) >= 2:
            rig.sim.daq.close()  # the board's port disappears, as when its cable is pulled

    try:
        plan = TimedPlan(
            "forced", duration_s=10.0, frequency_hz=5.0, amplitude_m=1e-3, settle_s=0.5
        )
        with pytest.raises(AcquisitionError, match=r"no board answered within 0.5 s"):
            record_timed(rig, path, plan, progress=unplug_after_a_second)
        # what reached the amplifier: setpoint zero, output disabled (with the DAQ emulator
        # closed the virtual rig's physics clock no longer runs, so its measured output
        # cannot ramp down here; the Ctrl-C test checks the measured ramp)
        assert rig.shaker.amplitude_m == 0.0
        assert not rig.shaker.enabled  # one register count
    finally:
        rig.close()
    with open_recording(path) as rec:
        status = rec.status()
        assert status.closed and status.stop_reason.startswith("error:")
        assert len(rec.channel("angle")) >= 2000
        assert rec.drive_log()["enabled"][-1] == 0  # the last row: the commanded stop


def test_record_refuses_an_existing_file_and_an_unwritable_folder_before_opening_devices(
    tmp_path, read_only_folder, capsys
):
    existing = tmp_path / "yesterday.h5"
    existing.write_bytes(b"precious")
    assert main(["record", "--sim", "--duration", "1", "--out", str(existing)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert existing.read_bytes() == b"precious"
    assert (
        main(["record", "--sim", "--duration", "1", "--out", str(read_only_folder / "run.h5")]) == 2
    )
    error = capsys.readouterr().err
    assert "not writable" in error and "opening the devices" not in error


def test_a_disk_that_fills_during_a_forced_run_stops_it_cleanly(two_megabyte_filesystem, capsys):
    path = two_megabyte_filesystem / "forced.h5"
    status = main(
        [
            "record",
            "--sim",
            "--experiment",
            "forced",
            "--drive-hz",
            "5",
            "--beta",
            "0.02",
            "--settle",
            "0.5",
            "--duration",
            "60",
            "--fs",
            "20000",
            "--out",
            str(path),
            "--quiet",
        ]
    )
    assert status == 2
    error = capsys.readouterr().err
    assert "disk almost full" in error and "ramped to zero" in error
    assert len(error.strip().splitlines()) == 1  # one line, not the log's copies of it
    with open_recording(path) as rec:
        status_row = rec.status()
        drive = rec.drive_log()
        drive = drive[drive["source"] == 0]  # commanded, not read back
        angle = rec.channel("angle")
    assert status_row.closed and "disk almost full" in status_row.stop_reason
    assert len(angle) >= 4_000  # what was recorded before the disk filled is kept, in order
    np.testing.assert_array_equal(np.diff(angle.indices), 1)
    assert drive["enabled"].tolist()[0] == 1 and drive["enabled"].tolist()[-1] == 0


def test_a_sweep_beyond_the_limits_is_refused_before_anything_moves(tmp_path, capsys):
    out = tmp_path / "too_fast.h5"
    status = main(
        [
            "sweep",
            "--sim",
            "--sweep",
            "frequency",
            "--start",
            "30",
            "--stop",
            "60",
            "--steps",
            "4",
            "--amplitude-mm",
            "1",
            "--out",
            str(out),
        ]
    )
    assert status == 2
    error = capsys.readouterr().err
    assert "frequency_hz = 50.0" in error and "[0.0, 40.0] Hz" in error
    assert "default_rig.toml" in error and "opening the devices" not in error
    assert not out.exists()
