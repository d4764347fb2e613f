"""Real recordings of the virtual rig, made once per session through the real command line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rig.cli import main
from tests.rig.cli_recording import start_forced_recording, wait_for_samples

REPO = Path(__file__).resolve().parents[2]


def run_cli(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    """``impact-rig ARGS`` in its own process, as a user runs it."""
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", *args],
        cwd=REPO, capture_output=True, text=True, timeout=timeout_s, check=False,
    )


@pytest.fixture(scope="session")
def recording(tmp_path_factory) -> Path:
    """A closed 2 s forced recording of the virtual rig."""
    path = tmp_path_factory.mktemp("recording") / "run.h5"
    status = main([
        "record", "--sim", "--experiment", "forced", "--drive-hz", "10", "--beta", "0.03",
        "--settle", "0.3", "--duration", "2", "--out", str(path), "--quiet",
        "--operator", "A. Tester",
    ])  # fmt: skip
    assert status == 0
    return path


@pytest.fixture(scope="session")
def killed_recording(tmp_path_factory) -> Path:
    """A recording whose writer was killed with SIGKILL after two seconds of samples."""
    path = tmp_path_factory.mktemp("killed") / "killed.h5"
    process = start_forced_recording(path)
    try:
        wait_for_samples(process, path, 4_000)
        time.sleep(0.5)
    finally:
        os.kill(process.pid, signal.SIGKILL)
        process.wait(10)
    return path
