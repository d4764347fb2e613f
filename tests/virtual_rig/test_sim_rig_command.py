"""`impact-rig sim-rig` as a user runs it: subprocess, endpoints on stdout, real clients, Ctrl-C."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import time
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.limits import ShakerLimits
from drivers.modbus_shaker import ModbusRtuBackend, ModbusTcpBackend
from drivers.serial_daq import SerialDaqBackend
from drivers.shaker import ShakerAmplifier
from tests.host_process import end, read_endpoints, start_rig_cli


@pytest.fixture
def sim_rig() -> Iterator[tuple[subprocess.Popen[str], dict[str, str]]]:
    process = start_rig_cli(
        "sim-rig", "--port", "0", "--rtu", "--angle-noise", "0", "--table-noise", "0", stdin=True
    )
    try:
        yield process, read_endpoints(process)
    finally:
        end(process)


def test_sim_rig_serves_its_endpoints_and_stops_on_ctrl_c(
    sim_rig: tuple[subprocess.Popen[str], dict[str, str]],
) -> None:
    process, endpoints = sim_rig
    host, _, port = endpoints["modbus-tcp"].rpartition(":")
    assert host == "127.0.0.1"  # loopback unless told otherwise
    tcp = ModbusTcpBackend(host, int(port), timeout_s=1.0)
    with ShakerAmplifier(tcp, ShakerLimits()) as shaker:
        shaker.ramp_rate_m_s = 0.01
        shaker.frequency_hz = 5.0
        shaker.amplitude_m = 0.002
        shaker.enabled = True
        settled = shaker.wait_settled(timeout_s=10.0)  # the world clock moves the shaker
        assert settled.amplitude_m == pytest.approx(0.002)
        assert process.stdin is not None and process.stdout is not None
        process.stdin.write("status\n")
        process.stdin.flush()
        reply = re.search(r"table=(\S+) m at (\S+) Hz", process.stdout.readline())
        assert reply is not None
        assert float(reply[1]) == pytest.approx(0.002, rel=1e-3)
        assert float(reply[2]) == pytest.approx(5.0, rel=1e-6)

        rtu = ModbusRtuBackend(endpoints["modbus-rtu"], timeout_s=1.0)
        rtu.open()
        try:
            assert rtu.read_input_registers(5, 3) == [0, 5000, 2000]  # same amplifier over RTU
        finally:
            rtu.close()

        daq = SerialDaqBackend(endpoints["daq-serial"])
        daq.connect()
        try:
            daq.configure(2000.0, (0, 1))
            daq.start()
            chunks, deadline = [], time.monotonic() + 10.0
            while sum(c.n_samples for c in chunks) < 3000 and time.monotonic() < deadline:
                chunk = daq.read_chunk(0.5)
                if chunk is not None:
                    chunks.append(chunk)
            daq.stop()
        finally:
            daq.close()
    table = np.concatenate([c.analog[:, 1] for c in chunks]).astype(float)
    tach = np.concatenate([c.digital & 1 for c in chunks]).astype(bool)
    assert table.size >= 3000
    # default calibration 3e-6 m per count: a 2 mm sine peaks near 667 counts
    assert np.max(np.abs(table)) == pytest.approx(0.002 / 3e-6, abs=3)
    assert np.all(np.abs(np.diff(np.flatnonzero(tach)) - 2000.0 / 5.0) <= 1)

    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=15)
    assert process.returncode == 0, err
    assert "stopped" in out


def test_sim_rig_on_a_port_in_use_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    from rig.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["sim-rig", "--port", str(port), "--no-daq"]) == 2
    err = capsys.readouterr().err
    assert f"could not start the virtual rig on 127.0.0.1:{port}" in err
    assert "--port 0" in err


@pytest.mark.parametrize(
    ("line", "words"),
    [
        ("trip meltdown", "expected one of over_amplitude, over_current"),
        ("fault flaky", "expected one of none, no_reply, device_failure, busy"),
        ("release far", "could not convert"),
        ("jump", "unknown command 'jump'"),
    ],
)
def test_bad_stdin_commands_name_what_was_wrong(line: str, words: str) -> None:
    from rig.commands.sim_rig import _command

    with pytest.raises(ValueError, match=words):
        _command(None, line.split())  # refused before it touches the rig
