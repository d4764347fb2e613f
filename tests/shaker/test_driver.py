"""The shaker driver's behaviour, identical on Modbus TCP and on the in-process backend."""

from __future__ import annotations

import time

import pytest

from drivers.amplifier_registers import Fault, Holding, Input
from drivers.interfaces import Actuator, DeviceError, LimitError, WrongDeviceError
from drivers.modbus_shaker import ModbusTcpBackend
from drivers.shaker import CommandRefusedError, ShakerAmplifier
from hardware_sim.amplifier_emulator import AmplifierEmulator
from tests.shaker.conftest import LIMITS, OUT_OF_LIMITS, Bench, make_firmware
from tests.shaker.sim_shaker_backend import SimShakerBackend


def test_settings_reach_the_registers_with_the_documented_scaling(bench: Bench) -> None:
    with bench.shaker() as shaker:
        shaker.frequency_hz = 12.345
        shaker.amplitude_m = 0.0012
        shaker.ramp_rate_m_s = 0.0025
        # docs/amplifier_registers.md: mHz as uint32 high word first, micrometres, um/s
        assert bench.firmware.read_holding(0, 4) == [0, 12345, 1200, 2500]
        assert shaker.frequency_hz == pytest.approx(12.345)
        assert shaker.amplitude_m == pytest.approx(0.0012)
        assert shaker.ramp_rate_m_s == pytest.approx(0.0025)
        shaker.frequency_hz = 39.0  # 39000 mHz still fits the low word; 70 kHz would not
        assert bench.firmware.read_holding(0, 2) == [0, 39000]


def test_frequency_above_one_word_uses_the_high_register(bench: Bench) -> None:
    with bench.shaker() as shaker:
        bench.forget_writes()
        shaker.limits = type(LIMITS)(max_frequency_hz=100.0)
        shaker.frequency_hz = 70.0  # 70 000 mHz = 0x0001 0x1170
        assert bench.setpoint_writes() == [(int(Holding.FREQUENCY_MHZ_HI), (1, 0x1170))]
        assert shaker.frequency_hz == pytest.approx(70.0)


@pytest.mark.parametrize(("setting", "value"), OUT_OF_LIMITS)
def test_out_of_range_setting_is_refused_and_never_written(
    bench: Bench, setting: str, value: object
) -> None:
    with bench.shaker() as shaker:
        shaker.frequency_hz = 10.0
        shaker.amplitude_m = 0.001
        shaker.ramp_rate_m_s = 0.01
        before = bench.firmware.read_holding(0, 8)
        bench.forget_writes()
        with pytest.raises(LimitError, match=setting):
            setattr(shaker, setting, value)
        assert bench.setpoint_writes() == []
        assert bench.firmware.read_holding(0, 8) == before


def test_drive_settles_at_its_setpoints_then_stops_at_zero(bench: Bench) -> None:
    with bench.shaker() as shaker:
        assert isinstance(shaker, Actuator)
        shaker.ramp_rate_m_s = 0.05
        shaker.frequency_hz = 8.0
        shaker.amplitude_m = 0.002
        shaker.enabled = True
        settled = shaker.wait_settled(timeout_s=5.0)
        assert settled.amplitude_m == pytest.approx(0.002, abs=1e-6)
        assert settled.frequency_hz == pytest.approx(8.0, abs=1e-3)
        status = shaker.status()
        assert status.connected and status.enabled and status.faults == ()
        assert status.measured["amplitude_m"] == pytest.approx(0.002, abs=1e-6)
        shaker.stop(wait_s=5.0)
        assert shaker.measured().at_zero
        assert not shaker.enabled


def test_leaving_the_with_block_ramps_the_drive_to_zero(bench: Bench) -> None:
    with bench.shaker() as shaker:
        shaker.ramp_rate_m_s = 0.05
        shaker.frequency_hz = 8.0
        shaker.amplitude_m = 0.002
        shaker.enabled = True
        shaker.wait_settled(timeout_s=5.0)
    assert not bench.firmware.enabled
    assert bench.firmware.read_holding(Holding.AMPLITUDE_UM, 1) == [0]
    assert bench.firmware.response.targets[0] == 0.0
    assert bench.firmware.faults == Fault(0)  # stopped by the host, not by the watchdog


def test_heartbeat_keeps_the_watchdog_quiet(bench: Bench) -> None:
    # 1 s of silence trips it: ten heartbeats missed in a row, not a busy machine's hiccup
    with bench.shaker(watchdog_s=1.0, heartbeat_period_s=0.1) as shaker:
        shaker.frequency_hz = 5.0
        shaker.amplitude_m = 0.001
        shaker.enabled = True
        time.sleep(2.5)  # two and a half watchdog periods
        assert shaker.faults() == ()
        assert shaker.enabled
        echo = bench.firmware.read_input(Input.HEARTBEAT_ECHO, 1)[0]
        assert echo > 0


def test_enable_refused_while_a_fault_is_latched_then_cleared(bench: Bench) -> None:
    with bench.shaker() as shaker:
        shaker.frequency_hz = 5.0
        shaker.amplitude_m = 0.001
        bench.firmware.trip(Fault.OVER_TEMPERATURE)
        assert shaker.faults() == ("over-temperature",)
        with pytest.raises(CommandRefusedError) as refused:
            shaker.enabled = True
        assert refused.value.code == 0x03
        # the refusal made the drive safe: amplitude setpoint back to zero
        assert bench.firmware.read_holding(Holding.AMPLITUDE_UM, 1) == [0]
        shaker.clear_faults()
        assert shaker.faults() == ()
        shaker.amplitude_m = 0.001
        shaker.enabled = True
        assert shaker.enabled


def test_interlock_cannot_be_cleared_while_open(bench: Bench) -> None:
    with bench.shaker() as shaker:
        bench.firmware.set_interlock(True)
        bench.firmware.trip(Fault.OVER_CURRENT)
        shaker.clear_faults()
        assert shaker.faults() == ("interlock open",)
        bench.firmware.set_interlock(False)
        shaker.clear_faults()
        assert shaker.faults() == ()


def test_wrong_device_identity_is_refused(bench: Bench) -> None:
    impostor = make_firmware(model_code=0x4441)  # e.g. a DAQ gateway at the same address
    if bench.emulator is not None:
        with AmplifierEmulator(impostor) as other:
            backend = ModbusTcpBackend("127.0.0.1", other.port, timeout_s=0.3, retries=0)
            with pytest.raises(WrongDeviceError, match="0x4441"):
                ShakerAmplifier(backend, LIMITS).connect()
    else:
        with pytest.raises(WrongDeviceError, match="0x4441"):
            ShakerAmplifier(SimShakerBackend(impostor), LIMITS).connect()
    assert not impostor.enabled


def test_status_of_an_unconnected_shaker_says_so(bench: Bench) -> None:
    shaker = bench.shaker()
    assert shaker.status().connected is False
    with pytest.raises(DeviceError, match="not connected"):
        shaker.amplitude_m = 0.001
