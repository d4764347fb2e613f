"""An unplugged virtual DAQ board hands the physics clock back to the rig's own clock."""

from __future__ import annotations

import time

from analysis.model import Model
from drivers.daq import DaqBoard
from drivers.sensors import PotentiometerAngleSensor, PotentiometerCalibration
from drivers.serial_daq import SerialDaqBackend
from hardware_sim.sim_rig import SimRig
from hardware_sim.virtual_rig import VirtualRigSettings


def test_time_moves_on_after_the_streaming_board_is_unplugged() -> None:
    sim = SimRig(VirtualRigSettings(model=Model(), sample_rate_hz=2000.0)).start()
    board = DaqBoard(
        SerialDaqBackend(sim.endpoints.daq_port), sample_rate_hz=2000.0, analog_channels=(0, 1)
    )
    try:
        board.open()
        angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
        angle.start()
        deadline = time.monotonic() + 10.0
        while angle.read(0.2) is None and time.monotonic() < deadline:
            pass
        assert sim.daq.firmware.streaming
        sim.daq.close()  # the cable is pulled while the board streams
        before = sim.rig.time_s
        time.sleep(1.0)
        # the world clock advances the physics again (0.0 s before the fix)
        assert sim.rig.time_s - before > 0.3
    finally:
        board.close()
        sim.stop()
