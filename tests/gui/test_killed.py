"""The whole GUI application killed with SIGKILL while it records: the file keeps all but
the last second, opens, exports, and repairs into a file any HDF5 tool opens.

A real Qt application (offscreen) in its own process group, recording the virtual rig
(DAQ on a pty, amplifier on Modbus TCP, in the application's process) through the main
window's own actions; the process group is killed as a crash or ``kill -9`` would.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest

from recording.reader import open_recording
from rig.recorder import MAX_FLUSH_INTERVAL_S
from tests.gui.record_until_killed import RATE_HZ
from tests.host_process import ROOT, start_rig_cli

BEFORE_KILL = 40_000  # two seconds taken in by the engine


@pytest.mark.timeout(180)
def test_the_gui_killed_while_recording_leaves_all_but_the_last_second(tmp_path):
    path = tmp_path / "gui_killed.h5"
    gui = subprocess.Popen(
        [sys.executable, "-m", "tests.gui.record_until_killed", str(path),
         str(tmp_path / "gui.ini")],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: the whole application is killed
        env={**os.environ, "PYTHONPATH": str(ROOT), "QT_QPA_PLATFORM": "offscreen"},
    )
    taken = 0
    try:
        assert gui.stdout is not None
        first = gui.stdout.readline()
        if first.strip() != "recording":
            gui.kill()
            pytest.fail(f"the GUI did not start recording: {first!r} {gui.stderr.read()}")
        for line in gui.stdout:
            taken = int(line.split()[1])
            if taken >= BEFORE_KILL:
                break
    finally:
        os.killpg(gui.pid, signal.SIGKILL)
        gui.wait(30)
    assert gui.returncode == -signal.SIGKILL and taken >= BEFORE_KILL

    with open_recording(path) as recording:
        recording.verify()
        assert not recording.status().closed  # cut short, and the file says so
        angle, table = recording.channel("angle"), recording.channel("table")
        notes = recording.info.notes
    assert notes == "killed GUI"
    # every sample of each channel from the recording's start to within the last second,
    # once, in order; the channels are flushed one after the other, so either may hold a
    # few more samples than the other when the kill comes (CI under load: table 32 400,
    # angle 32 200)
    assert table.indices[0] == angle.indices[0]
    for channel in (angle, table):
        np.testing.assert_array_equal(np.diff(channel.indices), 1)
        assert channel.indices[-1] + 1 >= taken - MAX_FLUSH_INTERVAL_S * RATE_HZ
    assert np.all(np.isfinite(angle.values)) and np.all(np.isfinite(table.values))

    # what a user does next: export it, and repair it for tools that do not read SWMR
    export = start_rig_cli("export", str(path), "--out", str(tmp_path / "gui_killed.csv"))
    _, err = export.communicate(timeout=120)
    assert export.returncode == 0, err
    repair = start_rig_cli("repair", str(path), "--out", str(tmp_path / "repaired.h5"))
    _, err = repair.communicate(timeout=120)
    assert repair.returncode == 0, err
    with h5py.File(tmp_path / "repaired.h5", "r") as repaired:
        assert repaired["channels/angle/raw"].shape[0] == len(angle)
