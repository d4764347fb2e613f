"""SIGTERM stops a headless recording as Ctrl-C does: drive to zero, file closed with its reason."""

from __future__ import annotations

import signal

from recording.reader import open_recording
from tests.rig.cli_recording import start_forced_recording, wait_for_samples


def test_sigterm_closes_the_recording_and_stops_the_drive(tmp_path):
    path = tmp_path / "terminated.h5"
    process = start_forced_recording(path)
    try:
        wait_for_samples(process, path, 2_000)
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    assert process.returncode == 130, stderr
    with open_recording(path) as rec:
        status = rec.status()
        assert status.closed
        assert "interrupted" in status.stop_reason
        drive = rec.drive_log()
        drive = drive[drive["source"] == 0]  # commanded, not read back
        assert drive["enabled"][0] == 1
        assert drive["enabled"][-1] == 0 or drive["amplitude_m"][-1] == 0.0
        assert len(rec.channel("angle")) >= 2_000
