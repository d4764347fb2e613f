"""The DAQ board emulator in its own process, so a benchmark measures only the host's cost."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


class EmulatorProcess:
    """``python -m hardware_sim.daq_emulator`` in real time; it exits when its stdin closes."""

    def __init__(self, *extra_args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "hardware_sim.daq_emulator", "--speed", "1", *extra_args],
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.process.stdout is not None
        self.port = self.process.stdout.readline().strip()
        if not self.port.startswith("/dev/"):
            self.close()
            raise RuntimeError(f"the emulator did not print its port (got {self.port!r})")

    def close(self) -> None:
        """Close its stdin and wait for it (kill it if it does not go)."""
        assert self.process.stdin is not None
        self.process.stdin.close()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
