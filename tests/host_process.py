"""The host software in its own process, as a user or a dying host runs it: start, read, end."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def start_python(*args: str, stdin: bool = False) -> subprocess.Popen[str]:
    """``python ARGS`` from the repository root with this checkout importable; stdout and
    stderr (and, with ``stdin``, stdin) are text pipes."""
    return subprocess.Popen(
        [sys.executable, *args],
        cwd=ROOT,
        stdin=subprocess.PIPE if stdin else None,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )


def start_rig_cli(*args: str, stdin: bool = False) -> subprocess.Popen[str]:
    """``impact-rig ARGS`` in its own process (see :func:`start_python`)."""
    return start_python("-m", "rig.cli", *args, stdin=stdin)


def read_endpoints(process: subprocess.Popen[str]) -> dict[str, str]:
    """The ``name: endpoint`` lines ``impact-rig sim-rig`` prints, up to its ``ready`` line."""
    assert process.stdout is not None
    endpoints: dict[str, str] = {}
    for line in process.stdout:
        if line.startswith("ready"):
            return endpoints
        name, _, value = line.partition(": ")
        endpoints[name.strip()] = value.strip()
    assert process.stderr is not None
    pytest.fail(f"sim-rig ended before it was ready: {process.stderr.read()}")


def end(process: subprocess.Popen[str], timeout_s: float = 10.0) -> None:
    """Kill ``process`` if it still runs, and reap it."""
    if process.poll() is None:
        process.kill()
        process.wait(timeout_s)
