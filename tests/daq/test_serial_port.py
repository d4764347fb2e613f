"""The serial backend against ports that are missing, silent, speak something else, or vanish.

Real pseudo-terminals throughout: the driver opens the slave by path, as it would
/dev/ttyACM0.  The board behind it is the Python emulator or the C firmware core's host
build (``make_pty_board``).
"""

from __future__ import annotations

import os
import threading
import time
import tty

import pytest

from drivers.daq import DaqBoard
from drivers.interfaces import DeviceError, DeviceNotFoundError, LimitError, WrongDeviceError
from drivers.sensors import PotentiometerAngleSensor, PotentiometerCalibration
from drivers.serial_daq import SerialDaqBackend
from hardware_sim.sample_source import CounterSource


def test_unknown_port_is_named_in_the_error():
    board = DaqBoard(SerialDaqBackend("/dev/ttyNOSUCH7"), sample_rate_hz=1000, analog_channels=(0,))
    with pytest.raises(DeviceNotFoundError, match="/dev/ttyNOSUCH7"):
        board.open()


def test_a_path_that_is_not_a_serial_port_is_refused(tmp_path):
    not_a_tty = tmp_path / "plain_file"
    not_a_tty.write_bytes(b"")
    with pytest.raises(DeviceNotFoundError, match="plain_file"):
        SerialDaqBackend(str(not_a_tty)).connect()


class OtherDevice:
    """A pty whose far end answers every line with ``answer`` (None: stays silent)."""

    def __init__(self, answer: bytes | None, *, hang_up: bool = False) -> None:
        self.hang_up = hang_up
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.answer = answer
        self.running = True
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        import select

        while self.running:
            readable, _, _ = select.select([self.master], [], [], 0.05)
            if readable:
                try:
                    data = os.read(self.master, 1024)
                except OSError:
                    return
                if self.hang_up and b"IDN?" in data:
                    os.close(self.master)  # the device vanishes as it is asked who it is
                    self.master = -1
                    return
                if self.answer is not None and b"\n" in data:
                    os.write(self.master, self.answer)

    def close(self) -> None:
        self.running = False
        self.thread.join()
        if self.master >= 0:
            os.close(self.master)
        os.close(self.slave)


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "answer",
    [None, b"HELLO from a GPS receiver\r\n", b"$GPGGA,123519,4807.038,N\r\n" * 40],
    ids=["silent", "text_reply", "nmea_flood"],
)
def test_something_that_is_not_the_board_is_a_wrong_device(answer):
    other = OtherDevice(answer)
    try:
        backend = SerialDaqBackend(other.port, reply_timeout_s=0.3)
        board = DaqBoard(backend, sample_rate_hz=1000, analog_channels=(0,))
        with pytest.raises(WrongDeviceError, match=rf"nothing on serial port {other.port}"):
            board.open()  # a hang here trips the test's timeout mark, not a timed assert
    finally:
        other.close()


def test_board_refusal_is_reported_with_its_reason(make_pty_board):
    emulator = make_pty_board(CounterSource(), speed=5)
    backend = SerialDaqBackend(emulator.port)
    backend.connect()
    with pytest.raises(DeviceError, match=r"refused CONF: rate 5 Hz out of range 10\.\.250000"):
        backend.configure(5.0, (0,))
    backend.start()
    with pytest.raises(DeviceError, match="busy: STOP before CONF"):
        backend.configure(1000.0, (0,))
    backend.stop()
    backend.close()


def test_emulator_closing_mid_stream_fails_the_stream_without_a_hang(make_pty_board):
    emulator = make_pty_board(CounterSource(), speed=5)
    board = DaqBoard(SerialDaqBackend(emulator.port), sample_rate_hz=20_000, analog_channels=(0,))
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    assert angle.read(1.0) is not None
    emulator.close()
    deadline = time.monotonic() + 5
    with pytest.raises(DeviceError, match=f"serial port {emulator.port} went away"):
        while time.monotonic() < deadline:
            angle.read(0.1)
    board.close()


def test_a_board_left_streaming_is_stopped_and_identified(make_pty_board):
    emulator = make_pty_board(CounterSource(), speed=5)
    first = SerialDaqBackend(emulator.port)
    first.connect()
    first.configure(20_000, (0, 1))
    first.start()
    first.close()  # a host that crashed without STOP
    time.sleep(0.1)
    board = DaqBoard(SerialDaqBackend(emulator.port), sample_rate_hz=20_000, analog_channels=(0,))
    assert board.open().model == "IRDAQ-4"
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    block = angle.read(1.0)
    assert block is not None and block.first_index == 0
    board.close()


def test_a_replugged_board_streams_again_after_close_and_open(tmp_path, make_pty_board):
    # The port path stays the same across the replug (like /dev/ttyACM0): a symlink.
    port = tmp_path / "ttyACM0"
    first = make_pty_board(CounterSource(), speed=5)
    port.symlink_to(first.port)
    board = DaqBoard(SerialDaqBackend(str(port)), sample_rate_hz=20_000, analog_channels=(0,))
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    angle.start()
    assert angle.read(1.0) is not None
    first.faults.unplug()
    deadline = time.monotonic() + 5
    with pytest.raises(DeviceError, match="went away"):
        while time.monotonic() < deadline:
            angle.read(0.1)
    angle.stop()
    board.close()
    second = make_pty_board(CounterSource(), speed=5)
    port.unlink()
    port.symlink_to(second.port)
    assert board.open().model == "IRDAQ-4"
    angle.start()
    block = angle.read(1.0)
    assert block is not None and block.first_index == 0 and block.lost_before == 0
    board.close()
    first.close()


def test_a_refused_configuration_leaves_the_port_closed(make_pty_board):
    emulator = make_pty_board(CounterSource(), speed=5)
    backend = SerialDaqBackend(emulator.port)
    board = DaqBoard(backend, sample_rate_hz=1e6, analog_channels=(0,))
    with pytest.raises(LimitError, match="outside the range"):
        board.open()
    assert backend._serial is None  # released: another program may open the port


def test_a_port_that_vanishes_while_connecting_is_not_called_a_wrong_device():
    other = OtherDevice(None, hang_up=True)
    try:
        backend = SerialDaqBackend(other.port, reply_timeout_s=0.5)
        with pytest.raises(DeviceError, match="went away") as caught:
            backend.connect()
        assert not isinstance(caught.value, WrongDeviceError)
        assert backend._serial is None  # the port was released
    finally:
        other.close()
