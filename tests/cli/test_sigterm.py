"""SIGTERM stops a headless recording as Ctrl-C does: drive to zero, file closed with its reason."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

from rig.recording_reader import open_recording

REPO = Path(__file__).resolve().parents[2]


def test_sigterm_closes_the_recording_and_stops_the_drive(tmp_path):
    path = tmp_path / "terminated.h5"
    command = [
        sys.executable,
        "-m",
        "rig.cli",
        "record",
        "--sim",
        "--experiment",
        "forced",
        "--drive-hz",
        "5",
        "--beta",
        "0.02",
        "--settle",
        "0.2",
        "--duration",
        "120",
        "--fs",
        "2000",
        "--out",
        str(path),
        "--quiet",
    ]
    process = subprocess.Popen(command, cwd=REPO, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            assert process.poll() is None, process.stderr.read()
            try:
                with open_recording(path) as live:
                    if len(live.channel("angle")) >= 2_000:
                        break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.2)
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
        assert drive["enabled"][0] == 1
        assert drive["enabled"][-1] == 0 or drive["amplitude_m"][-1] == 0.0
        assert len(rec.channel("angle")) >= 2_000
