"""Generated input at the Modbus boundary (both ways, real pymodbus over loopback TCP) and on
the command line (every ``impact-rig`` sub-command).

Bounded and deterministic: derandomized Hypothesis, a fixed number of examples, no example
database; ``benchmarks/fuzz.py`` runs the same checks for as long as asked.  How each
answer is judged: ``harness.fuzz.modbus`` and ``harness.fuzz.command_line``.
"""

from __future__ import annotations

import pytest
from hypothesis import given

from drivers.interfaces import DeviceError
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import ShakerAmplifier
from harness.fuzz.command_line import check_command_line, command_lines, commands, inputs
from harness.fuzz.modbus import (
    LIMITS,
    TIMEOUT_S,
    WATCHDOG_S,
    ManglingProxy,
    amplifier,
    check_driver,
    check_server,
    driver_cases,
    hostile_requests,
    reset,
)
from tests.fuzz.test_boundaries import bounded


@pytest.fixture(scope="module")
def emulator():
    served = amplifier()
    yield served
    served.stop()


@bounded(25)
@given(case=driver_cases(reconnect=False))
def test_the_shaker_driver_answers_a_mangling_amplifier_in_one_line_and_leaves_it_off(
    emulator, case
):
    check_driver(emulator, case)


@bounded(25)
@given(requests=hostile_requests())
def test_the_amplifier_emulator_survives_hostile_requests_and_keeps_its_ranges(
    emulator, requests
):
    check_server(emulator, requests)


@pytest.mark.parametrize(
    ("fate", "words"),
    [
        ("short", "a garbled reply to a read of 3 register(s) at 0: it holds 1"),
        ("huge", "beyond the amplifier's own range: a garbled reply"),
        ("reset", "connection lost during FC4 read of 5 input register(s) at 3"),
    ],
)
def test_a_reply_that_cannot_be_the_amplifiers_is_refused_not_passed_on(emulator, fate, words):
    # found by the driver's fuzzing: a read answered with fewer registers than asked raised
    # ValueError out of connect(); words beyond the amplifier's ranges came back as a
    # measured drive of 4,259,770 Hz; found by the soak: a connection reset by the controller
    # raised ConnectionResetError out of measured()
    reset(emulator.firmware)
    first = [fate] if fate == "short" else ["pass", "pass", fate]  # identify, or measure
    proxy = ManglingProxy(emulator.port, first, seed=0)
    backend = ModbusTcpBackend("127.0.0.1", proxy.port, timeout_s=TIMEOUT_S, retries=0)
    shaker = ShakerAmplifier(backend, LIMITS, watchdog_s=WATCHDOG_S)
    try:
        with pytest.raises(DeviceError) as refused:
            shaker.connect()
            shaker.measured()
        assert words in str(refused.value) and "\n" not in str(refused.value)
    finally:
        shaker.close()
        proxy.close()


@pytest.fixture(scope="module")
def command_inputs(tmp_path_factory):
    return inputs(tmp_path_factory.mktemp("inputs"))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("name", list(commands()))
def test_every_command_ends_well_or_refuses_in_one_line(name, command_inputs, tmp_path_factory):
    @bounded(2)
    @given(argv=command_lines(name, command_inputs))
    def one(argv):
        check_command_line(argv, tmp_path_factory.mktemp("run"))

    one()


# found by benchmarks/fuzz.py's command-line boundary (10 minutes, 2026-11-30): an empty
# FILE or --out became Path('.'), whose name-less with_name/with_suffix raised a ValueError
# the command had not foreseen ("PosixPath('.') has an empty name")
@pytest.mark.parametrize("argv", [
    ["repair", ""],
    ["repair", "0", "--out", ""],
    ["repair", "{recording}", "--out", ""],
    ["export", "{recording}", "--out", ""],
    ["export", "{recording}", "--out", "."],
    ["record", "--sim", "--out", ""],
    ["sweep", "--sim", "--sweep", "frequency", "--start", "5", "--stop", "6",
     "--beta", "0.02", "--out", ""],
], ids=" ".join)
def test_an_empty_file_name_is_refused_in_one_line(argv, command_inputs, tmp_path):
    recording = command_inputs[0]
    argv = [a.format(recording=recording) for a in argv]
    assert check_command_line(argv, tmp_path) == "refused"
