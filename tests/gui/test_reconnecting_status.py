"""The status panel says when the DAQ board is being reached again, and recovers on its own.

A real Qt widget (offscreen) fed by a real acquisition engine over the serial driver and
the board emulator on a pty whose stable path disappears and comes back.
"""

from __future__ import annotations

from drivers.daq import DaqBoard
from drivers.interfaces import ActuatorStatus
from drivers.sensors import PotentiometerAngleSensor, PotentiometerCalibration
from drivers.serial_daq import SerialDaqBackend
from gui.panels.status import StatusPanel
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.sample_source import CounterSource
from rig.engine import AcquisitionEngine
from tests.gui.conftest import wait_until


def test_the_status_panel_shows_the_board_reconnecting_then_streaming(qapp, tmp_path):
    port = tmp_path / "ttyACM0"
    first = DaqEmulator(CounterSource(), speed=1.0).start()
    port.symlink_to(first.port)
    board = DaqBoard(
        SerialDaqBackend(str(port)),
        sample_rate_hz=10_000.0,
        analog_channels=(0,),
        reconnect_for_s=30.0,
        reconnect_interval_s=0.05,
    )
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    engine = AcquisitionEngine([angle])
    panel = StatusPanel()
    panel.show()
    second = None

    def refresh() -> str:
        panel.show_engine(engine.stats(), [("angle", angle.status())], 0)
        return panel.text("daq")

    try:
        engine.start()
        wait_until(qapp, lambda: refresh() == "streaming, healthy", 20, "healthy streaming")
        first.close()
        port.unlink()
        wait_until(qapp, lambda: "reconnecting to the DAQ board" in refresh(), 20, "reconnecting")
        assert "the run goes on" in panel.text("daq")
        second = DaqEmulator(CounterSource(), speed=1.0).start()
        port.symlink_to(second.port)
        wait_until(
            qapp, lambda: "reconnecting" not in refresh() and "away for" in refresh(), 20, "back"
        )
        assert "gaps in the data" in panel.text("lost")
        assert engine.running
    finally:
        engine.stop()
        board.close()
        first.close()
        if second is not None:
            second.close()
        panel.close()


def test_the_status_panel_shows_the_shaker_reconnecting(qapp):
    panel = StatusPanel()
    lost = "communication lost: shaker amplifier at Modbus TCP 127.0.0.1:5020: no reply"
    panel.show_shaker(ActuatorStatus(False, False, faults=(f"{lost}; reconnecting",)))
    assert panel.text("shaker") == "reconnecting (drive off until asked again)"
    panel.show_shaker(ActuatorStatus(False, False, faults=(lost,)))
    assert panel.text("shaker") == "not connected"
    panel.close()
