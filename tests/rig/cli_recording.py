"""A long forced recording of the virtual rig through the real CLI, for tests that stop it."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from recording.reader import open_recording

REPO = Path(__file__).resolve().parents[2]


def start_forced_recording(path: Path) -> subprocess.Popen[str]:
    """``impact-rig record --sim`` of a 5 Hz drive for up to two minutes, writing ``path``."""
    command = [
        sys.executable, "-m", "rig.cli", "record", "--sim", "--experiment", "forced",
        "--drive-hz", "5", "--beta", "0.02", "--settle", "0.2", "--duration", "120",
        "--fs", "2000", "--out", str(path), "--quiet",
    ]  # fmt: skip
    return subprocess.Popen(
        command, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )


def wait_for_samples(
    process: subprocess.Popen[str], path: Path, samples: int, timeout_s: float = 120.0
) -> None:
    """Block until a SWMR reader sees ``samples`` angle samples in the file being written."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise AssertionError(f"the recording ended early: {process.stderr.read()}")
        try:
            with open_recording(path) as live:
                if len(live.channel("angle")) >= samples:
                    return
        except (OSError, ValueError, KeyError):
            pass  # not created, or its layout not yet flushed
        time.sleep(0.2)
    raise AssertionError(f"no {samples} samples in {path} within {timeout_s} s")
