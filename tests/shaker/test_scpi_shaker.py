"""The SCPI generator drive: pyvisa (pyvisa-py) talking TCP to the emulated generator on loopback.

Settings reach the generator in Vpp through the gain and are confirmed; limits refuse a
value before the wire; each fault of the generator gives a one-line error and leaves
the output off; the output is off after every way out.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator

import pytest

from drivers.interfaces import (
    Actuator,
    DeviceError,
    DeviceNotFoundError,
    LimitError,
    WrongDeviceError,
)
from drivers.scpi_shaker import (
    MIN_VPP,
    InstrumentError,
    RampInterruptedError,
    ScpiLink,
    ScpiLinkError,
    ScpiShaker,
    SettingNotConfirmedError,
)
from hardware_sim.scpi_generator import GeneratorFault, ScpiGeneratorEmulator
from tests.shaker.conftest import LIMITS, OUT_OF_LIMITS

GAIN_M_PER_V = 1.0e-3  # 1 mm of table amplitude per volt of generator amplitude
TIMEOUT_S = 0.3
STEP_S = 0.01  # quick host ramp steps


@pytest.fixture
def generator() -> Iterator[ScpiGeneratorEmulator]:
    with ScpiGeneratorEmulator() as running:
        yield running


def make_shaker(generator: ScpiGeneratorEmulator, **options: object) -> ScpiShaker:
    link = ScpiLink(generator.resource, timeout_s=TIMEOUT_S)
    settings: dict[str, object] = {"gain_m_per_v": GAIN_M_PER_V, "ramp_step_s": STEP_S}
    settings.update(options)
    return ScpiShaker(link, LIMITS, **settings)  # type: ignore[arg-type]


def driving(generator: ScpiGeneratorEmulator, shaker: ScpiShaker) -> None:
    """Drive at 10 Hz, 1 mm (2 Vpp), ramped at the fastest allowed rate."""
    shaker.ramp_rate_m_s = LIMITS.max_ramp_rate_m_s
    shaker.frequency_hz = 10.0
    shaker.amplitude_m = 0.001
    shaker.enabled = True
    assert generator.state.output and generator.state.amplitude_vpp == pytest.approx(2.0)


def volt_writes(lines: list[str]) -> list[float]:
    return [
        float(line.split(";")[0].split()[1]) for line in lines if line.startswith("SOUR1:VOLT ")
    ]


def test_settings_go_out_in_vpp_through_the_gain_and_are_read_back(generator) -> None:
    with make_shaker(generator) as shaker:
        assert isinstance(shaker, Actuator)
        assert shaker.identity is not None and shaker.identity.serial == "SIM00001"
        s = generator.state
        assert (s.function, s.unit, s.offset_v, s.output) == ("SIN", "VPP", 0, False)
        generator.clear_log()
        shaker.frequency_hz = 12.345
        shaker.amplitude_m = 0.0012  # output off: set at once; 2 * 1.2 mm / (1 mm/V) = 2.4 Vpp
        assert generator.received == [
            "SOUR1:FREQ 12.345;*OPC?", "SYST:ERR?", "SOUR1:FREQ?",
            "SOUR1:VOLT 2.4;*OPC?", "SYST:ERR?", "SOUR1:VOLT?",
        ]  # fmt: skip
        assert (generator.state.frequency_hz, generator.state.amplitude_vpp) == (12.345, 2.4)
        assert shaker.frequency_hz == pytest.approx(12.345)
        assert shaker.amplitude_m == pytest.approx(0.0012)
        held = shaker.setpoints()
        assert (held.frequency_hz, held.enabled) == (pytest.approx(12.345), False)
        assert shaker.measured().amplitude_m == 0.0  # output off: nothing reaches the table


def test_output_goes_on_at_the_smallest_amplitude_and_ramps_up_then_down(generator) -> None:
    with make_shaker(generator) as shaker:
        shaker.ramp_rate_m_s = 0.01  # 20 Vpp/s: steps of at most 0.2 Vpp every 10 ms
        shaker.frequency_hz = 8.0
        shaker.amplitude_m = 0.001
        generator.clear_log()
        shaker.enabled = True
        lines = generator.received
        on = lines.index("OUTP1 ON;*OPC?")
        assert volt_writes(lines[:on]) == [MIN_VPP]  # never switched on at full amplitude
        up = volt_writes(lines[on:])
        assert up[-1] == 2.0 and up == sorted(up)
        steps = [b - a for a, b in zip([MIN_VPP, *up], up, strict=False)]
        assert max(steps) <= 0.2 + 1e-9 and len(up) == math.ceil((2.0 - MIN_VPP) / 0.2)
        assert shaker.measured().amplitude_m == pytest.approx(0.001)
        assert not shaker.measured().ramping
        generator.clear_log()
        shaker.stop()
        down = volt_writes(generator.received)
        assert down == sorted(down, reverse=True) and down[-1] == MIN_VPP
        assert generator.received[-1] == "OUTP1 OFF;OUTP1?"
        assert not generator.state.output and not shaker.enabled


@pytest.mark.parametrize(("setting", "value"), OUT_OF_LIMITS)
def test_a_setting_outside_the_limits_never_reaches_the_generator(
    generator, setting: str, value: object
) -> None:
    with make_shaker(generator) as shaker:
        driving(generator, shaker)
        before = generator.state
        generator.clear_log()
        with pytest.raises(LimitError, match=setting):
            setattr(shaker, setting, value)
        assert generator.received == []
        assert generator.state == before


def test_an_amplitude_beyond_the_generators_volts_is_refused_before_the_wire(generator) -> None:
    with make_shaker(generator, max_output_vpp=5.0) as shaker:  # 5 Vpp = 2.5 mm at 1 mm/V
        generator.clear_log()
        with pytest.raises(LimitError, match=r"amplitude_m.*max_output_vpp 5 Vpp"):
            shaker.amplitude_m = 0.003  # inside LIMITS (5 mm), not inside the generator's 5 Vpp
        assert generator.received == []


@pytest.mark.parametrize(
    ("fault", "setting", "value", "error", "words"),
    [
        (GeneratorFault.NO_ANSWER, "frequency_hz", 11.0, ScpiLinkError, "no answer to 'SOUR1:FREQ"),
        (GeneratorFault.QUEUE_ERROR, "frequency_hz", 11.0, InstrumentError, '-221,"Settings'),
        (GeneratorFault.IGNORE_FREQUENCY, "frequency_hz", 11.0, SettingNotConfirmedError, "10"),
        (GeneratorFault.CLIP_AMPLITUDE, "amplitude_m", 0.002, SettingNotConfirmedError, "3 Vpp"),
    ],
)
def test_each_generator_fault_gives_one_line_and_leaves_the_output_off(
    generator, fault: GeneratorFault, setting: str, value: float, error: type, words: str
) -> None:
    generator.clip_vpp = 3.0
    with make_shaker(generator) as shaker:
        driving(generator, shaker)
        generator.fault = fault
        with pytest.raises(error) as caught:
            setattr(shaker, setting, value)
        message = str(caught.value)
        assert "\n" not in message
        assert setting in message and words in message and "the output was" in message
        # the off command was sent before the error was raised; the emulator may still be
        # reading it from the socket, so wait on its state (bounded)
        assert generator.wait_for(lambda state: not state.output, 2.0)
    assert not generator.state.output


def test_after_no_answer_the_link_is_not_trusted_again(generator) -> None:
    with make_shaker(generator) as shaker:
        generator.fault = GeneratorFault.NO_ANSWER
        with pytest.raises(ScpiLinkError):
            shaker.frequency_hz = 11.0
        generator.fault = GeneratorFault.NONE  # a late reply could now be read as the next one
        with pytest.raises(DeviceError, match="communication failed earlier"):
            shaker.frequency_hz = 12.0
        assert not shaker.connected
        assert shaker.status().faults[0].startswith("communication lost")


@pytest.mark.parametrize("way_out", ["close", "with", "exception"])
def test_the_output_is_off_after_every_way_out(generator, way_out: str) -> None:
    shaker = make_shaker(generator)
    if way_out == "close":
        shaker.connect()
        driving(generator, shaker)
        shaker.close()
        shaker.close()  # twice is harmless
    elif way_out == "with":
        with shaker:
            driving(generator, shaker)
    else:
        with pytest.raises(KeyboardInterrupt), shaker:
            driving(generator, shaker)
            raise KeyboardInterrupt  # not even an Exception: the output still goes off
    assert not generator.state.output
    assert generator.received[-1] == "OUTP1 OFF;OUTP1?"
    assert generator.watchdog_trips == 0  # the host turned it off, not the emulator
    with pytest.raises(DeviceError, match="not connected"):
        shaker.amplitude_m = 0.001


def test_a_generator_already_driving_is_left_alone_with_a_one_line_error(generator) -> None:
    generator.set_output(True)
    with pytest.raises(DeviceError, match="output 1 is already on") as caught:
        make_shaker(generator).connect()
    assert "\n" not in str(caught.value)
    assert generator.received == ["*IDN?", "OUTP1?"]  # nothing changed on it
    assert generator.state.output


def test_something_else_on_the_port_is_not_taken_for_a_generator() -> None:
    with ScpiGeneratorEmulator(identity="hello") as other:
        with pytest.raises(WrongDeviceError, match="'hello'"):
            make_shaker(other).connect()
        assert other.received == ["*IDN?"]


def test_nothing_listening_is_a_one_line_device_not_found(generator) -> None:
    resource = generator.resource
    generator.stop()
    with pytest.raises(DeviceNotFoundError, match="connection refused") as caught:
        ScpiShaker(ScpiLink(resource, timeout_s=TIMEOUT_S), LIMITS, gain_m_per_v=1e-3).connect()
    assert "\n" not in str(caught.value)


def test_close_says_so_when_the_generator_does_not_confirm_the_output_off(generator) -> None:
    shaker = make_shaker(generator).connect()
    driving(generator, shaker)
    generator.fault = GeneratorFault.NO_ANSWER  # it still carries out commands
    with pytest.raises(DeviceError, match="could not confirm the output off") as caught:
        shaker.close()
    assert "\n" not in str(caught.value) and "switch it off at the generator" in str(caught.value)
    assert generator.wait_for(lambda state: not state.output, 2.0)  # the blind OFF arrived
    assert not shaker.connected


def test_stop_from_another_thread_cuts_a_ramp_short_and_the_output_goes_off(generator) -> None:
    with make_shaker(generator, ramp_step_s=0.02) as shaker:
        shaker.ramp_rate_m_s = 1e-3  # 1 mm takes 1 s: the stop comes in the middle
        shaker.frequency_hz = 10.0
        shaker.amplitude_m = 0.001
        outcome: list[BaseException | None] = []

        def enable() -> None:
            try:
                shaker.enabled = True
                outcome.append(None)
            except DeviceError as error:
                outcome.append(error)

        generator.clear_log()
        ramping = threading.Thread(target=enable)
        ramping.start()
        assert generator.wait_for(lambda state: state.output, 5.0)
        shaker.stop()
        ramping.join(5.0)
        assert isinstance(outcome[0], RampInterruptedError)
        assert not generator.state.output
        assert max(volt_writes(generator.received)) < 2.0  # never the full amplitude (2 Vpp)
